#!/usr/bin/env python3
"""How far any warp can even out a large subject's size without more angle error than
the conformal warp's (issue 13, "Large subjects"; ``tests/warp/bound.py``):

    .venv/bin/python tools/measure_large_bound.py [--cases sphere-concave:quarter,...]
        [--mus 0.03,0.1,0.3,1] [--step 8] [--free]
    .venv/bin/python tools/measure_large_bound.py --harmonic

For each case: the conformal warp's angle error and size inconsistency on the subject
(the quality tests' scorer at ``--step``), then for ``mu = 0`` and each of ``--mus``
the optimised warp's, as ratios to the conformal warp's. The unknowns are the conformal
warp's grid vertices shown through the per-pixel display (what the engine's grid can
show); ``--free``: every sample's content position (any warp, finer than the grid), and
the least size spread of an exactly conformal map of the subject's piece of surface.

``--harmonic`` (a few seconds): for every doubly curved surface and subject, the least
size spread of any angle-preserving warp of the subject's piece of surface, from the
conformal warp's own per-pixel measures (the quality tests' scorer at 4 px; asserted
in ``tests/warp/test_quality.py``), next to what the engine reaches there.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.threads import apply_thread_policy
from tests.distortion import in_mask
from tests.warp.bound import conformal_bound, harmonic_residual, sweep
from tests.warp.conftest import distortion, subject_masks

SHORT = "sphere-concave:quarter,sphere-concave:half,bowl:quarter,bowl:half,sphere-convex:half"


def main() -> None:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cases", default=SHORT + ",sphere-convex:quarter")
    ap.add_argument("--mus", default="0.5,1,1.5,2")
    ap.add_argument("--step", type=int, default=8)
    ap.add_argument("--free", action="store_true", help="any warp, not just the grid's")
    ap.add_argument("--harmonic", action="store_true", help="the angle-preserving bound")
    args = ap.parse_args()
    if args.harmonic:
        harmonic()
        return
    mus = tuple(float(m) for m in args.mus.split(",") if m)
    for case in args.cases.split(","):
        name, mask = case.split(":")
        t0 = time.perf_counter()
        pb, conf, points = sweep(name, mask, mus, args.step, on_grid=not args.free)
        line = f"{name:15s} {mask:8s} conformal angle {conf.angle:.5f} size {conf.size:.5f} |"
        for p, _ in points:
            line += (
                f" mu {p.mu:g}: size {p.size / conf.size:.2f}x angle {p.angle / conf.angle:.2f}x"
            )
            line += f"{' FOLDS' if p.folds else ''};"
        if args.free:
            bound = conformal_bound(pb, points[0][1]) / conf.size
            line += f" exactly conformal: >= {bound:.2f}x"
        print(f"{line} ({time.perf_counter() - t0:.0f} s)", flush=True)


def harmonic() -> None:
    """The least size spread of an angle-preserving warp, per surface and subject."""
    print("ratios to the conformal warp's size inconsistency on the subject")
    print(f"{'surface':15s} {'subject':9s} {'angle-preserving best':>22s} {'engine':>7s}")
    for name in ("sphere-concave", "sphere-convex", "bowl"):
        conf = distortion(name, "conformal")
        for mask in ("one-left", "face", "quarter", "half"):
            d = conf.select(in_mask(conf, subject_masks()[mask]))
            z = d.centroid_xy[:, 0] + 1j * d.centroid_xy[:, 1]
            best = harmonic_residual(z, d.log_size) / d.size_std
            ours = distortion(name, "content", mask)
            got = ours.select(in_mask(ours, subject_masks()[mask])).size_std / d.size_std
            print(f"{name:15s} {mask:9s} {best:21.2f}x {got:6.2f}x", flush=True)


if __name__ == "__main__":
    main()
