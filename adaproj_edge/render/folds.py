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


def guard(
    map_xy: NDArray[np.float32], fallback: NDArray[np.float32]
) -> tuple[NDArray[np.float32], int]:
    """``map_xy`` (H, W, 2) made fold-free where it folds.

    Around the folded pixels the map is replaced, with a smooth ramp, by its own
    smooth interpolation from the pixels around them (a normalised Gaussian blur that
    leaves the folded ones out: over a thin region an average of an orientation-keeping
    map keeps its orientation); the region grows until nothing folds, and if that takes
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
        size = (0, 0)
        den = cv2.GaussianBlur(known, size, sigma)
        num = cv2.GaussianBlur(values * known[..., None], size, sigma)
        with np.errstate(invalid="ignore", divide="ignore"):
            fill = num / den[..., None]
        outside = np.where(region, 0, 255).astype(np.uint8)
        dist = cv2.distanceTransform(outside, cv2.DIST_L2, 3)
        t = np.clip(1.0 - dist / ramp, 0.0, 1.0)
        share = np.where(np.isfinite(fill).all(axis=2), t * t * (3.0 - 2.0 * t), 0.0)
        out = (map_xy + share[..., None] * (fill - map_xy)).astype(np.float32)
        still = fold_mask(out)
        if not still.any():
            return out, int(np.count_nonzero(share > 0))
        region |= np.asarray(cv2.dilate(still.astype(np.uint8), kernel, iterations=2)) > 0
        ramp *= 1.5
        sigma *= 1.5
    return fallback, int(np.count_nonzero(np.isfinite(fallback[..., 0])))
