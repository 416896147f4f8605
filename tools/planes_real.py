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
  points (``tests/realframes.py``'s ``plane_spread``). A planar region's figure cannot
  be verified below this; seen grazing it is large, since an error of the plane's
  normal of d radians reads as about tan(incidence) d of angle.

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
    angle_size,
    box_points,
    figures,
    fit_plane,
    jacobians,
    load_frames,
    plane_spread,
    plane_tol,
    real_samples,
    to_p,
)


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
    return (fig.angle, fig.size, *angle_size(J))


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
            pa, ps, deg = plane_spread(frame, region)
            print(
                f"{frame.name + '/' + region.name:28} {sa:6.3f} {ss:6.3f} {oa:6.3f} {os_:6.3f} "
                f"{pa:6.3f} {ps:6.3f}  {deg:.2f} deg",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
