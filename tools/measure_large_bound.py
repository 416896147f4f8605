#!/usr/bin/env python3
"""How far any warp can even out a large subject's size without more angle error than
the conformal warp's (issue 13, "Large subjects"; ``tests/warp/bound.py``):

    .venv/bin/python tools/measure_large_bound.py [--cases sphere-concave:quarter,...]
        [--mus 0.03,0.1,0.3,1] [--step 8] [--free]
    .venv/bin/python tools/measure_large_bound.py --harmonic
    .venv/bin/python tools/measure_large_bound.py --curvature

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

``--curvature`` (~1 min): the large-subject line of ``tests/warp/test_quality.py``. For
every doubly curved surface (and a saddle) and subject, the least size spread of any
angle-preserving map of the subject's footprint computed from the surface's Gaussian
curvature (``tests/curvature_bound.py``), for the footprint the content warp gives the
subject and the conformal warp's, and what the engine reaches, all as ratios to the
conformal warp's size inconsistency there, and the angle error's ratio.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.geometry.analytic import NON_DEVELOPABLE, get_surface, simulate_surface
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from tests.curvature_bound import curvature_bound, paraboloid_curvature
from tests.distortion import in_mask, measure
from tests.warp.bound import conformal_bound, harmonic_residual, sweep
from tests.warp.conftest import CONTENT, distortion, subject_masks, surface, warped
from tools.bench_warp import Saddle

SHORT = "sphere-concave:quarter,sphere-concave:half,bowl:quarter,bowl:half,sphere-convex:half"


def main() -> None:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cases", default=SHORT + ",sphere-convex:quarter")
    ap.add_argument("--mus", default="0.5,1,1.5,2")
    ap.add_argument("--step", type=int, default=8)
    ap.add_argument("--free", action="store_true", help="any warp, not just the grid's")
    ap.add_argument("--harmonic", action="store_true", help="the angle-preserving bound")
    ap.add_argument("--curvature", action="store_true", help="the bound from curvature")
    args = ap.parse_args()
    if args.harmonic:
        harmonic()
        return
    if args.curvature:
        curvature()
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


def curvature() -> None:
    """The curvature bound and the engine, per surface and subject (the saddle's warps
    made here, on the full-resolution surface as the quality tests' are)."""
    print("ratios to the conformal warp's size inconsistency (angle: to its angle error)")
    print(f"{'surface':15s} {'subject':8s} {'bound(content)':>14s} {'bound(conf)':>11s}", end="")
    print(f" {'engine':>7s} {'angle':>6s} line")
    saddle = Saddle()
    for name in (*NON_DEVELOPABLE, "saddle"):
        shape = saddle if name == "saddle" else get_surface(name)
        s = simulate_surface(shape) if name == "saddle" else surface(name)
        kappa = paraboloid_curvature(saddle.k, -1.0) if name == "saddle" else None
        maps = {}
        for mask in (None, "face", "quarter", "half"):
            if name == "saddle":
                cmap = None if mask is None else subject_masks()[mask]
                mode = "conformal" if mask is None else "content"
                w = compute_warp(s, CONTENT, cmap, WarpSettings(mode=mode))
                maps[mask] = map_from_warp(w, s)
            else:
                maps[mask] = warped(name, "conformal" if mask is None else "content", mask)[1]
        conf = measure(maps[None], shape, s.projector.K)
        for mask in ("face", "quarter", "half"):
            m = subject_masks()[mask]
            c = conf.select(in_mask(conf, m))
            d = measure(maps[mask], shape, s.projector.K)
            d = d.select(in_mask(d, m))
            b_ours = curvature_bound(maps[mask], shape, s.projector.K, m, curvature=kappa)
            b_conf = curvature_bound(maps[None], shape, s.projector.K, m, curvature=kappa)
            line = d.size_std <= max(0.6 * c.size_std, 1.05 * b_ours) and d.angle_mean <= (
                c.angle_mean
            )
            print(
                f"{name:15s} {mask:8s} {b_ours / c.size_std:13.3f}x {b_conf / c.size_std:10.3f}x"
                f" {d.size_std / c.size_std:6.3f}x {d.angle_mean / c.angle_mean:5.2f}x"
                f" {'met' if line else 'MISSED'}",
                flush=True,
            )


if __name__ == "__main__":
    main()
