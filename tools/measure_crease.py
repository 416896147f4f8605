#!/usr/bin/env python3
"""Print the displayed map's distortion on wall corners whose crease falls on or near a
grid line (issue 30), scored like the tests (``tests/distortion.py``: the rendered
per-pixel map against rays cast at the analytic surface, every 4 px, small triangles
across the crease left out), with the corners of ``tests/render/test_crease_display.py``:

    .venv/bin/python tools/measure_crease.py [--mode content] [--mask half]

Per corner: mean angle error and size inconsistency over the picture, the worst 4-px
triangle's angle error and log-size deviation, and how many triangles exceed 0.01
(a band along the crease shows as hundreds of them).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from tests.distortion import measure
from tests.render.test_crease_display import CASES, corner_on_line
from tests.warp.conftest import CONTENT, subject_masks


def main() -> None:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--mode", default="content", choices=("content", "conformal"))
    ap.add_argument("--mask", default="half", help="subject mask (tests/warp/conftest.py)")
    args = ap.parse_args()
    cmap = subject_masks()[args.mask] if args.mode == "content" else None
    print(
        f"{'corner':30s} {'angle':>9s} {'size':>9s} {'worst a':>8s} {'worst s':>8s} {'>0.01':>6s}"
    )
    for case in CASES:
        analytic = corner_on_line(*case.values)
        surface = simulate_surface(analytic)
        warp = compute_warp(surface, CONTENT, cmap, WarpSettings(mode=args.mode))
        d = measure(map_from_warp(warp, surface), analytic, surface.projector.K)
        dev = np.abs(d.log_size - np.median(d.log_size))
        over = int(np.sum((d.angle > 0.01) | (dev > 0.01)))
        print(
            f"{case.id:30s} {d.angle_mean:9.6f} {d.size_std:9.6f} {d.angle.max():8.4f} "
            f"{dev.max():8.4f} {over:6d}",
            flush=True,
        )


if __name__ == "__main__":
    main()
