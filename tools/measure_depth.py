#!/usr/bin/env python3
"""Print the depth -> surface numbers behind the issue's "done when" items.

    .venv/bin/python tools/measure_depth.py

1. Surface at the warp grid's 21x21 vertices vs ground truth, every depth frame of
   each committed fixture session (moving and still): median and p95 error.
2. Distortion of the warp from the estimated surface vs the warp from the true surface
   (device held still for 2 s), scored by tests/distortion.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.geometry.analytic import SURFACES  # noqa: E402
from adaproj_edge.session.reader import read_session  # noqa: E402
from adaproj_edge.session.simulator import scene_of_session  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from tests.geometry.test_depth_accuracy import FIXTURES, grid_errors  # noqa: E402
from tests.geometry.test_depth_warp import distortions  # noqa: E402


def main() -> int:
    apply_thread_policy()
    print("surface at grid vertices (all frames of each fixture)")
    for name in ("corner", "cylinder", "sphere", "mesh-sphere"):
        s = read_session(FIXTURES / f"{name}.mcap")
        spec = s.truth_surface_spec()
        assert spec is not None
        e = grid_errors(s.records, s.calibration, scene_of_session(spec, s.attachments))
        print(
            f"  {name:12s} nodes {e.size:5d}  median {1000 * np.median(e):5.2f} mm"
            f"  p95 {1000 * np.percentile(e, 95):5.2f} mm  max {1000 * e.max():5.1f} mm"
        )
    print("warp distortion, estimated vs true surface (angle mean, size std)")
    for name in SURFACES:
        est, true = distortions(name)
        print(
            f"  {name:16s} angle {est.angle_mean:.4f} / {true.angle_mean:.4f}"
            f" = {est.angle_mean / max(true.angle_mean, 1e-9):4.2f}x   size {est.size_std:.4f} /"
            f" {true.size_std:.4f} = {est.size_std / max(true.size_std, 1e-9):4.2f}x"
            f"  folds {est.folds}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
