#!/usr/bin/env python3
"""Print the engine's distortion figures on every built-in surface (issue 2's targets).

Scored like the tests (``tests/distortion.py``: the rendered per-pixel map against rays
cast at the analytic surface), at the default 20x20 grid:

    .venv/bin/python tools/measure_warp.py
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.geometry.analytic import NON_DEVELOPABLE, SURFACES
from adaproj_edge.threads import apply_thread_policy
from tests.distortion import in_mask, visible_fraction
from tests.warp.conftest import CONTENT, distortion, subject_masks, warped


def main() -> None:
    apply_thread_policy()
    print(
        f"{'surface':17s} {'mode':9s} {'angle err':>9s} {'size inc.':>9s} "
        f"{'folds':>5s} {'shown':>6s}"
    )
    for name in SURFACES:
        for mode in ("standard", "conformal", "content"):
            d = distortion(name, mode)
            shown = visible_fraction(warped(name, mode)[1], CONTENT)
            print(
                f"{name:17s} {mode:9s} {d.angle_mean:9.4f} {d.size_std:9.4f} "
                f"{d.folds:5d} {shown:6.1%}"
            )
    print("\nsubject masks on non-developable surfaces (inside the mask, content / conformal):")
    for name in NON_DEVELOPABLE:
        for mask_name, mask in subject_masks().items():
            conf = distortion(name, "conformal")
            cont = distortion(name, "content", mask_name)
            paper = distortion(name, "content", mask_name, "paper")
            a = conf.select(in_mask(conf, mask))
            b = cont.select(in_mask(cont, mask))
            p = paper.select(in_mask(paper, mask))
            print(
                f"{name:17s} {mask_name:10s} size {b.size_std:.4f}/{a.size_std:.4f} "
                f"= {b.size_std / a.size_std:.2f}x   angle {b.angle_mean:.4f}/{a.angle_mean:.4f} "
                f"= {b.angle_mean / a.angle_mean:.2f}x   (paper's alternation: size "
                f"{p.size_std / a.size_std:.2f}x, angle {p.angle_mean / a.angle_mean:.2f}x)"
            )


if __name__ == "__main__":
    main()
