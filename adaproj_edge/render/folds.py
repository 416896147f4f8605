"""No folds in what is displayed: a per-pixel map checked pixel by pixel, and a local,
counted fallback where it would fold.

The perspective-correct interpolation of a mesh that keeps its orientation keeps it
too: in each triangle it is a projective map of the triangle onto itself, and it is
continuous across edges. The surface-based map (:mod:`adaproj_edge.render.seams`) is
exact where the other is not, but at a curved crease its correction may turn a few
pixels over (the crease is not where the two planes of the triangle meet). :func:`guard`
finds the pixels whose two small triangles (to the right and below, as a scorer
samples them) are reversed or collapsed and smooths the map over them, growing the
region until nothing folds; it returns how many pixels took part of their value from
the fallback.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray

RAMP = 3.0  # pixels over which the fallback fades out (and the blur's first width)
ROUNDS = 8  # growing rounds before the whole map falls back


def fold_mask(map_xy: NDArray[np.floating]) -> BoolArray:
    """(H, W) pixels whose triangles to the right and below (both shown) are reversed
    or collapsed in content space."""
    m = map_xy.astype(np.float64)
    c0 = m[:-1, :-1]
    right, diag, down = m[:-1, 1:] - c0, m[1:, 1:] - c0, m[1:, :-1] - c0
    with np.errstate(invalid="ignore"):
        upper = right[..., 0] * diag[..., 1] - right[..., 1] * diag[..., 0]
        lower = diag[..., 0] * down[..., 1] - diag[..., 1] * down[..., 0]
        bad = (upper <= 0) | (lower <= 0)  # NaN (not shown) compares False
    out = np.zeros(map_xy.shape[:2], dtype=bool)
    out[:-1, :-1] = bad
    return out


def _smooth(
    values: NDArray[np.float32],
    known: NDArray[np.float32],
    region: BoolArray,
    sigma: float,
    ramp: float,
) -> NDArray[np.float64]:
    """The map ``values`` (H, W, 2) interpolated over ``region`` from the ``known``
    pixels around it: at each pixel the value at it of the plane fitted to the known
    ones, weighted by a Gaussian of width ``sigma`` (NaN far from any, and outside the
    window ``ramp`` plus 4 ``sigma`` around the region).

    A plane, not a mean: next to the map's outline (a silhouette, the frame's edge) the
    known pixels lie on one side only, and their mean is the value of a pixel inside -
    a map pulled inward there, its outline too, and with it the content placed up to
    the outline (issue 13: a cylinder on a floor, its crease through the frame's edge).
    The plane keeps an affine map as it is, outline included; where the known pixels
    do not span a plane (a thin line of them) their mean stands.
    """
    h, w = known.shape
    fill = np.full((h, w, 2), np.nan)
    ys, xs = np.nonzero(region)
    pad = int(np.ceil(ramp + 3.0 * sigma))
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, h)
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, w)
    k = known[y0:y1, x0:x1].astype(np.float32)
    # coordinates and values about the window's middle (the blurs run in float32)
    v = values[y0:y1, x0:x1].astype(np.float64)
    mean = (v * k[..., None]).sum(axis=(0, 1)) / max(float(k.sum()), 1.0)
    v = v - mean
    yy, xx = np.mgrid[0 : y1 - y0, 0 : x1 - x0].astype(np.float32)
    yy -= np.float32(0.5 * (y1 - y0 - 1))
    xx -= np.float32(0.5 * (x1 - x0 - 1))

    def blur(a: NDArray[np.float32]) -> NDArray[np.float64]:
        out = cv2.GaussianBlur(a, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
        return np.asarray(out, dtype=np.float64)

    # Gaussian moments of the known pixels about each pixel (dx = x' - x, dy = y' - y)
    s0, sx, sy = blur(k), blur(k * xx), blur(k * yy)
    sxx, sxy, syy = blur(k * xx * xx), blur(k * xx * yy), blur(k * yy * yy)
    x, y = xx.astype(np.float64), yy.astype(np.float64)
    mx, my = sx - x * s0, sy - y * s0
    mxx = sxx - 2.0 * x * sx + x * x * s0
    mxy = sxy - x * sy - y * sx + x * y * s0
    myy = syy - 2.0 * y * sy + y * y * s0
    # the plane's value at the pixel: [1 0 0] M^-1 r, M the moments' 3x3 matrix
    a00 = mxx * myy - mxy * mxy  # cofactors of M's first row
    a01 = my * mxy - mx * myy
    a02 = mx * mxy - my * mxx
    det = s0 * a00 + mx * a01 + my * a02
    with np.errstate(invalid="ignore", divide="ignore"):
        # a sound plane: the known pixels spread both ways (det well away from 0)
        sound = det > 1e-3 * s0 * s0 * s0 * sigma**4
        for c in range(2):
            f = (k * v[..., c]).astype(np.float32)
            r0, rx, ry = blur(f), blur(f * xx), blur(f * yy)
            rx, ry = rx - x * r0, ry - y * r0
            plane = (a00 * r0 + a01 * rx + a02 * ry) / det
            fill[y0:y1, x0:x1, c] = np.where(sound, plane, r0 / s0) + mean[c]
    return fill


def guard(
    map_xy: NDArray[np.float32], fallback: NDArray[np.float32]
) -> tuple[NDArray[np.float32], int]:
    """``map_xy`` (H, W, 2) made fold-free where it folds.

    Around the folded pixels the map is replaced, with a smooth ramp, by its own
    smooth interpolation from the pixels around them (a Gaussian-weighted plane fit that
    leaves the folded ones out, :func:`_smooth`: over a thin region it keeps an
    orientation-keeping map's orientation, and next to the outline the outline); the
    region grows until nothing folds, and if that takes
    too long the perspective-correct ``fallback`` (H, W, 2) is shown instead.

    Returns the map and the number of pixels that take part of their value from a
    fallback (0: the map was kept as it is).
    """
    bad = fold_mask(map_xy)
    if not bad.any():
        return map_xy, 0
    kernel = np.ones((3, 3), np.uint8)
    region = np.asarray(cv2.dilate(bad.astype(np.uint8), kernel)) > 0
    shown = np.asarray(np.isfinite(map_xy).all(axis=2), dtype=bool)
    values = np.where(shown[:, :, None], map_xy, 0.0).astype(np.float32)
    ramp, sigma = RAMP, RAMP
    for _ in range(ROUNDS):
        known = (shown & ~region).astype(np.float32)
        fill = _smooth(values, known, region, sigma, ramp)
        outside = np.where(region, 0, 255).astype(np.uint8)
        dist = cv2.distanceTransform(outside, cv2.DIST_L2, 3)
        t = np.clip(1.0 - dist / ramp, 0.0, 1.0)
        share = np.where(np.isfinite(fill).all(axis=2), t * t * (3.0 - 2.0 * t), 0.0)
        blend = map_xy + share[..., None] * (fill - map_xy)
        out = np.where(share[..., None] > 0, blend, map_xy).astype(np.float32)
        still = fold_mask(out)
        if not still.any():
            return out, int(np.count_nonzero(share > 0))
        region |= np.asarray(cv2.dilate(still.astype(np.uint8), kernel, iterations=2)) > 0
        ramp *= 1.5
        sigma *= 1.5
    return fallback, int(np.count_nonzero(np.isfinite(fallback[..., 0])))
