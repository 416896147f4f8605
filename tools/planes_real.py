#!/usr/bin/env python3
"""Where the distortion on the real frames' planar regions comes from.

For every planar region of ``tests/fixtures/real/`` (run through the device as
``tools/bench_real.py`` runs it) prints three pairs of figures, angle / size:

- ``shown``: the figure the tests assert, the picture against the robust plane fitted
  to the raw points of the region's box (``tests/realframes.py``);
- ``own``: the same picture against the device's own surface, on the same triangles:
  what the warp leaves on the surface it was given (a shown figure well above it is
  the surface's error; one close to it, the warp's);
- ``spread``: what the measure reads between two robust plane fits of the same raw
  points (the box's left and right halves, then its top and bottom halves; the larger
  of the two): content laid exactly on one read against the other. A planar region's
  figure cannot be verified below this; seen grazing it is large, since an error of
  the plane's normal of d radians reads as about tan(incidence) d of angle.

Always exits 0: it measures, the tests assert.

    .venv/bin/python tools/planes_real.py [--frame NAME]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.threads import apply_thread_policy
from tests.realframes import (
    FIXTURES,
    RealFrame,
    Region,
    box_points,
    figures,
    fit_plane,
    jacobians,
    load_frames,
    plane_hits,
    plane_tol,
    real_samples,
    rig,
    to_p,
)


def _angle_size(J: np.ndarray) -> tuple[float, float]:
    sv = np.linalg.svd(J, compute_uv=False)
    return float(np.mean(sv[:, 0] / sv[:, 1] - 1)), float(np.std(0.5 * np.log(sv[:, 0] * sv[:, 1])))


def spread(frame: RealFrame, region: Region) -> tuple[float, float, float]:
    """(angle, size, degrees between the fits) between the plane fits of the box's
    halves, the larger pair, over the projector's samples on the region's plane."""
    cal = rig(frame, region)
    K = cal.projector.K
    uv, real = real_samples(frame, cal)
    u0, v0, u1, v1 = region.plane_box
    pts = to_p(cal, box_points(frame, region.plane_box))
    tol = plane_tol(frame, float(np.nanmedian(pts[:, 2])))
    n, d, inl = fit_plane(pts, tol)
    with np.errstate(invalid="ignore"):
        on = np.abs(real @ n - d) < tol
    v, u = np.mgrid[v0:v1, u0:u1]
    u, v = u.reshape(-1), v.reshape(-1)
    e1 = np.cross(n, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    worst = (0.0, 0.0, 0.0)
    for coord in (u, v):
        half = coord < np.median(coord[inl])
        na, da, _ = fit_plane(pts[inl & half], tol)
        nb, db, _ = fit_plane(pts[inl & ~half], tol)
        xa, xb = plane_hits(na, da, uv, K), plane_hits(nb, db, uv, K)
        keep = on & np.isfinite(xa).all(axis=-1) & np.isfinite(xb).all(axis=-1)
        flat = np.stack([xa @ e1, xa @ e2], axis=-1)
        J = max((jacobians(xb, keep, flat * s)[0] for s in ([1, 1], [1, -1])), key=len)
        a, s = _angle_size(J)
        deg = float(np.degrees(np.arccos(min(1.0, abs(float(na @ nb))))))
        if a > worst[0]:
            worst = (a, s, deg)
    return worst


def own(frame: RealFrame, region: Region) -> tuple[float, float, float, float]:
    """(shown angle, size, own angle, size) of the device's picture."""
    fig, run = figures(frame, region, render=False)
    if run.map_xy is None or run.surface is None:
        return fig.angle, fig.size, float("nan"), float("nan")
    cal = run.calibration
    uv, real = real_samples(frame, cal)
    xy = run.map_xy[uv[..., 1].astype(int), uv[..., 0].astype(int)].astype(np.float64)
    pts = to_p(cal, box_points(frame, region.plane_box))
    tol = plane_tol(frame, float(np.nanmedian(pts[:, 2])))
    n, d, _ = fit_plane(pts, tol)
    with np.errstate(invalid="ignore"):
        on = np.abs(real @ n - d) < tol
    X = run.surface.points_at(uv).astype(np.float64)
    keep = on & np.isfinite(xy).all(axis=-1) & np.isfinite(X).all(axis=-1)
    J, _ = jacobians(X, keep, xy)
    return (fig.angle, fig.size, *_angle_size(J))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frame", action="append", help="only these frames (by name)")
    args = ap.parse_args(argv)
    apply_thread_policy()
    frames = [f for f in load_frames(FIXTURES) if not args.frame or f.name in args.frame]
    print(f"{'region':28} {'shown':>13} {'own':>13} {'spread':>13}  fits apart")
    for frame in frames:
        for region in frame.regions:
            if not region.planar:
                continue
            sa, ss, oa, os_ = own(frame, region)
            pa, ps, deg = spread(frame, region)
            print(
                f"{frame.name + '/' + region.name:28} {sa:6.3f} {ss:6.3f} {oa:6.3f} {os_:6.3f} "
                f"{pa:6.3f} {ps:6.3f}  {deg:.2f} deg",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
