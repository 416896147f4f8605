#!/usr/bin/env python3
"""How far any warp can even out a large subject's size without more angle error than
the conformal warp's (issue 13, "Large subjects"; ``tests/warp/bound.py``):

    .venv/bin/python tools/measure_large_bound.py [--cases sphere-concave:quarter,...]
        [--mus 0.03,0.1,0.3,1] [--step 8] [--free]
    .venv/bin/python tools/measure_large_bound.py --harmonic
    .venv/bin/python tools/measure_large_bound.py --curvature
    .venv/bin/python tools/measure_large_bound.py --photos

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

``--photos`` (~3 min): the same line for scikit-image photos (the cat ``chelsea``,
``coffee``, ``rocket``, ``checkerboard``) with a centred half-image subject, each content
map made as ``adaproj warp --mode content --mask`` makes it (saliency, faces, the
mask), on the four smooth doubly curved surfaces: the content warp's size spread and
angle error on the subject against the conformal warp's, the curvature bound, the
faces found and the guard's choice.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from adaproj_edge.geometry.analytic import (
    NON_DEVELOPABLE,
    AnalyticSurface,
    get_surface,
    simulate_surface,
)
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from tests.curvature_bound import Curvature, curvature_bound, paraboloid_curvature
from tests.distortion import in_mask, measure
from tests.warp.bound import conformal_bound, harmonic_residual, sweep
from tests.warp.conftest import CONTENT, distortion, subject_masks, surface
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
    ap.add_argument("--photos", action="store_true", help="the line for photos")
    args = ap.parse_args()
    if args.harmonic:
        harmonic()
        return
    if args.curvature:
        curvature()
        return
    if args.photos:
        photos()
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
    for name, shape, s, kappa in _smooth_surfaces():
        maps = {}
        for mask in (None, "face", "quarter", "half"):
            cmap = None if mask is None else subject_masks()[mask]
            mode = "conformal" if mask is None else "content"
            maps[mask] = map_from_warp(compute_warp(s, CONTENT, cmap, WarpSettings(mode=mode)), s)
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


def _smooth_surfaces() -> list[tuple[str, AnalyticSurface, Surface, Curvature | None]]:
    """The smooth doubly curved surfaces and a saddle: name, analytic surface, the
    simulated one and the saddle's curvature (the others have their own)."""
    saddle = Saddle()
    out: list[tuple[str, AnalyticSurface, Surface, Curvature | None]] = [
        (n, get_surface(n), surface(n), None) for n in NON_DEVELOPABLE
    ]
    out.append(("saddle", saddle, simulate_surface(saddle), paraboloid_curvature(saddle.k, -1)))
    return out


def photos() -> None:
    """The large-subject line for photos with a centred half subject."""
    import cv2
    from skimage import data

    from adaproj_edge.content.contentmap import content_map_for

    print("content warp against the conformal warp on the half subject")
    print(
        f"{'surface':15s} {'image':13s} {'size':>6s} {'angle':>6s} {'bound':>6s} line  faces guard"
    )
    for name, shape, s, kappa in _smooth_surfaces():
        for image_name in ("chelsea", "coffee", "rocket", "checkerboard"):
            image = getattr(data, image_name)()
            code = cv2.COLOR_GRAY2BGR if image.ndim == 2 else cv2.COLOR_RGB2BGR
            image = cv2.cvtColor(image, code)
            h, w = image.shape[:2]
            yy, xx = np.mgrid[0:h, 0:w]
            half = ((xx - 0.5 * w) / (0.4 * w)) ** 2 + ((yy - 0.5 * h) / (0.4 * h)) ** 2 <= 1
            mask = half.astype(np.float32)
            cmap = content_map_for(image, mask)
            figures = []
            for mode, given in (("conformal", None), ("content", cmap)):
                warp = compute_warp(s, (w, h), given, WarpSettings(mode=mode))
                shown = map_from_warp(warp, s)
                d = measure(shown, shape, s.projector.K)
                figures.append((d.select(in_mask(d, mask)), shown, warp))
            (conf, _, _), (ours, shown, warp) = figures
            bound = curvature_bound(shown, shape, s.projector.K, mask, curvature=kappa)
            size, angle = ours.size_std / conf.size_std, ours.angle_mean / conf.angle_mean
            met = ours.size_std <= max(0.6 * conf.size_std, 1.05 * bound) and angle <= 1.0
            print(
                f"{name:15s} {image_name:13s} {size:5.3f}x {angle:5.3f}x"
                f" {bound / conf.size_std:5.3f}x {'met ' if met else 'MISS'}"
                f" {len(cmap.faces):5d} {warp.meta['guard']['choice']}",
                flush=True,
            )


if __name__ == "__main__":
    main()
