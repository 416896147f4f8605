#!/usr/bin/env python3
"""How much a real sensor bends a flat surface: the curvature of its disparity's slow error.

For every planar box of ``tests/fixtures/real/`` (each frame's floor box and the plane
box of each wall and floor region) the raw points are fitted with a robust plane
(``tests/realframes.py``'s RANSAC, inliers within 1.5 depth steps). A plane's disparity
``f B / z`` is exactly affine in the depth camera's normalised image coordinates
``(x, y) = ((u - cx) / fx, (v - cy) / fy)``, so two halves of a flat surface have the
same affine disparity; whatever tilts them apart is the sensor's bend (or a surface
that is not flat). The inliers are split in halves (left / right, then top / bottom),
an affine disparity is fitted to each (thousands of pixels: the steps and the random
error average out), and of the two splits the one whose halves differ more is printed:

- ``z``: median depth (m); ``r``: the inliers' range of image radius ``sqrt(x^2 + y^2)``;
- ``inl``: the fraction of the box's points on its plane (below 0.8 the box is not one
  plane and is left out of the summary);
- ``curve``: the halves' disparity gradients' difference over twice the distance of
  their centroids (px per unit of normalised coordinate squared): the curvature of the
  quadratic slow error that would tilt them so (``SensorKind.curve_px`` in
  ``adaproj_edge/geometry/depth/sensor.py`` is the largest of these);
- ``deg``: the dihedral between the halves' planes; ``off_mm``: how far apart their
  planes' depths are along the seam between them (median).

Always exits 0: it measures.

    .venv/bin/python tools/measure_sensor_bend.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.realframes import FIXTURES, FloatArray, RealFrame, fit_plane, load_frames, plane_tol

BLOCK = 8  # pixels: the block medians' size
MIN_INLIERS = 0.8  # a box with fewer of its points on its plane is not one plane


def boxes(frame: RealFrame) -> list[tuple[str, tuple[int, int, int, int]]]:
    """The frame's floor box and its wall and floor regions' plane boxes (no repeats)."""
    out = [("floor_box", frame.floor_box)]
    for r in frame.regions:
        if r.planar and all(r.plane_box != b for _, b in out):
            out.append((f"{r.name} ({r.kind})", r.plane_box))
    return out


def _affine(x: FloatArray, y: FloatArray, d: FloatArray) -> FloatArray:
    """Least-squares ``d = a + b x + c y``: (a, b, c)."""
    A = np.stack([np.ones_like(x), x, y], axis=1)
    coef: FloatArray = np.linalg.lstsq(A, d, rcond=None)[0]
    return coef


def bend(frame: RealFrame, box: tuple[int, int, int, int]) -> dict[str, float]:
    """The figures of one box (see the module's docstring)."""
    u0, v0, u1, v1 = box
    pts = frame.points()[v0:v1, u0:u1].reshape(-1, 3)
    z_med = float(np.nanmedian(pts[:, 2]))
    _, _, inl = fit_plane(pts, plane_tol(frame, z_med))
    fb = frame.K[0, 0] * frame.baseline_m
    v, u = np.mgrid[v0:v1, u0:u1].astype(np.float64)
    x = ((u - frame.K[0, 2]) / frame.K[0, 0]).ravel()[inl]
    y = ((v - frame.K[1, 2]) / frame.K[1, 1]).ravel()[inl]
    disp = fb / pts[inl, 2]
    out = {
        "z": z_med,
        "r0": float(np.hypot(x, y).min()),
        "r1": float(np.hypot(x, y).max()),
        "inl": float(inl.mean()),
        "curve": 0.0,
        "deg": 0.0,
        "offset_mm": 0.0,
    }
    for c in (x, y):  # left / right, then top / bottom halves
        half = c < np.median(c)
        ga, gb = _affine(x[half], y[half], disp[half]), _affine(x[~half], y[~half], disp[~half])
        sep = float(np.hypot(x[half].mean() - x[~half].mean(), y[half].mean() - y[~half].mean()))
        curve = float(np.hypot(*(ga[1:] - gb[1:]))) / (2.0 * sep)
        # the halves' planes in 3D (n . X = d from disparity = fb (n . ray) / d)
        na, nb = ga[[1, 2, 0]], gb[[1, 2, 0]]
        na, nb = na / np.linalg.norm(na), nb / np.linalg.norm(nb)
        deg = float(np.degrees(np.arccos(min(1.0, abs(float(na @ nb))))))
        # their depths apart at the seam (the median of the split coordinate)
        seam = np.abs(c - np.median(c)) < 0.01
        da = ga[0] + ga[1] * x[seam] + ga[2] * y[seam]
        db = gb[0] + gb[1] * x[seam] + gb[2] * y[seam]
        off = float(np.median(np.abs(fb / da - fb / db))) * 1e3
        if curve > out["curve"]:
            out.update(curve=curve, deg=deg, offset_mm=off)
    return out


def main() -> int:
    print(
        f"{'frame':15} {'box':22} {'z':>5} {'r':>9} {'inl':>5} {'curve':>6} {'deg':>5} "
        f"{'off_mm':>6}"
    )
    worst: list[float] = []
    for frame in load_frames(FIXTURES):
        for name, box in boxes(frame):
            f = bend(frame, box)
            flag = "" if f["inl"] >= MIN_INLIERS else "  (not one plane: left out)"
            if not flag:
                worst.append(f["curve"])
            print(
                f"{frame.name:15} {name:22} {f['z']:5.2f} {f['r0']:4.2f}-{f['r1']:4.2f} "
                f"{f['inl']:5.2f} {f['curve']:6.2f} {f['deg']:5.2f} {f['offset_mm']:6.1f}{flag}"
            )
    print(f"\nlargest curvature over {len(worst)} planar boxes: {max(worst):.2f} px")
    print(f"median: {float(np.median(worst)):.2f} px")
    return 0


if __name__ == "__main__":
    sys.exit(main())
