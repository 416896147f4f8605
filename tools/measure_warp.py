#!/usr/bin/env python3
"""Print the engine's distortion figures on every built-in surface (issues 2 and 13).

Scored like the tests (``tests/distortion.py``: the rendered per-pixel map against rays
cast at the analytic surface), at the default 20x20 grid:

    .venv/bin/python tools/measure_warp.py [--surfaces bumps,waves] [--masks face,half]

First table: every mode without a subject, over everything shown (angle error, size
inconsistency, folded 4-px triangles, fraction of the content shown). Second: content
mode with each subject mask: folds and coverage everywhere; on developable surfaces the
distortion over everything (exact: <= 0.005); on the others the subject's distortion
against the conformal warp's on the same subject (ratios, ``<= 1.0x`` is the target,
``<= 0.6x`` in size for subjects up to half the image on smooth doubly curved
surfaces), and the paper's alternation as written for comparison.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.geometry.analytic import SURFACES
from adaproj_edge.threads import apply_thread_policy
from tests.distortion import in_mask, visible_fraction
from tests.warp.conftest import CONTENT, distortion, subject_masks, warped


def main() -> None:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--surfaces", default=",".join(SURFACES))
    ap.add_argument("--masks", default=",".join(subject_masks()))
    ap.add_argument("--no-paper", action="store_true", help="skip the paper's alternation")
    args = ap.parse_args()
    names = [n for n in args.surfaces.split(",") if n]
    masks = [m for m in args.masks.split(",") if m]
    print(
        f"{'surface':15s} {'mode':9s} {'angle err':>9s} {'size inc.':>9s} "
        f"{'folds':>5s} {'shown':>7s} {'s':>5s}"
    )
    for name in names:
        for mode in ("standard", "conformal", "content"):
            t0 = time.perf_counter()
            d = distortion(name, mode)
            shown = visible_fraction(warped(name, mode)[1], CONTENT)
            print(
                f"{name:15s} {mode:9s} {d.angle_mean:9.4f} {d.size_std:9.4f} "
                f"{d.folds:5d} {shown:7.2%} {time.perf_counter() - t0:5.1f}",
                flush=True,
            )
    print("\ncontent mode with a subject (developable: everything; others: the subject, ")
    print("content / conformal on the same subject; paper = the paper's alternation):")
    for name in names:
        developable = SURFACES[name].developable
        conf = distortion(name, "conformal")
        for mask_name in masks:
            mask = subject_masks()[mask_name]
            cont = distortion(name, "content", mask_name)
            warp, m = warped(name, "content", mask_name)
            shown = visible_fraction(m, CONTENT)
            choice = warp.meta.get("guard", {}).get("choice", "-")
            head = f"{name:15s} {mask_name:9s} folds {cont.folds:3d} shown {shown:7.2%}"
            if developable:
                print(
                    f"{head}  angle {cont.angle_mean:.4f} size {cont.size_std:.4f} [{choice}]",
                    flush=True,
                )
                continue
            a = conf.select(in_mask(conf, mask))
            b = cont.select(in_mask(cont, mask))
            line = (
                f"{head}  size {b.size_std:.4f}/{a.size_std:.4f} = "
                f"{b.size_std / a.size_std:.2f}x  angle {b.angle_mean:.4f}/{a.angle_mean:.4f} "
                f"= {b.angle_mean / a.angle_mean:.2f}x [{choice}]"
            )
            if not args.no_paper:
                paper = distortion(name, "content", mask_name, "paper")
                p = paper.select(in_mask(paper, mask))
                line += (
                    f"  (paper: size {p.size_std / a.size_std:.2f}x, "
                    f"angle {p.angle_mean / a.angle_mean:.2f}x, folds {paper.folds})"
                )
            print(line, flush=True)


if __name__ == "__main__":
    main()
