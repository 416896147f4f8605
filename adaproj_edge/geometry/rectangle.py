"""The maximal inscribed axis-aligned rectangle of a given aspect inside a triangle mesh.

Paper §4.1: the content rectangle becomes the maximal inscribed rectangle (same aspect
ratio, upright) of the region the warped mesh covers, so no content is ever lost.

The region (union of triangles, holes included) is rasterised with the aspect ratio
folded into the y axis, so the wanted rectangle becomes a square; the largest square
inside a raster region centred on a pixel has half-side equal to that pixel's
chessboard (L-infinity) distance to the outside, which ``cv2.distanceTransform``
gives exactly. The raster is eroded by one pixel first, so the result lies inside
the region.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.projector import FloatArray

RASTER = 1024
_SHIFT = 4


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle ``[x0, x0 + width] x [y0, y0 + height]``."""

    x0: float
    y0: float
    width: float
    height: float


def coverage_raster(
    triangles: FloatArray, aspect: float, size: int = RASTER
) -> tuple[np.ndarray, float, float, float]:
    """Rasterise triangles (T, 3, 2) with y scaled by ``aspect`` (= width / height).

    Returns the mask (uint8), the raster cell size and the origin (x, y') of the raster.
    """
    pts = triangles.reshape(-1, 2).copy()
    pts[:, 1] *= aspect
    lo = pts.min(axis=0)
    hi = pts.max(axis=0)
    extent = float(np.max(hi - lo))
    if not np.isfinite(extent) or extent <= 0:
        raise WarpError("the warped mesh has no area")
    cell = extent / (size - 3)
    origin = lo - 1.5 * cell
    shape = (int(np.ceil((hi[1] - lo[1]) / cell)) + 4, int(np.ceil((hi[0] - lo[0]) / cell)) + 4)
    mask = np.zeros(shape, dtype=np.uint8)
    q = np.rint((pts - origin) / cell * (1 << _SHIFT)).astype(np.int32).reshape(-1, 3, 2)
    cv2.fillPoly(mask, list(q), 1, lineType=cv2.LINE_8, shift=_SHIFT)
    return mask, cell, float(origin[0]), float(origin[1])


def inscribed_rectangle(
    triangles: FloatArray, aspect: float, prefer: FloatArray | None = None
) -> Rect:
    """Largest rectangle of ``aspect`` (width / height) inside the union of ``triangles``.

    Parameters
    ----------
    triangles : (T, 3, 2) float array
        The covered region, as triangles (holes are simply absent triangles).
    aspect : float
        Width over height of the wanted rectangle.
    prefer : (2,) float array, optional
        Among equally large rectangles, the one whose centre is nearest this point.
    """
    if triangles.size == 0:
        raise WarpError("no surface triangles to place the content on")
    mask, cell, ox, oy = coverage_raster(triangles, aspect)
    mask = cv2.erode(mask, np.ones((3, 3), np.uint8))
    dist = cv2.distanceTransform(mask, cv2.DIST_C, 3)
    best = float(dist.max())
    if best < 2:
        raise WarpError("the covered region is too small to place the content")
    rows, cols = np.nonzero(dist >= best)
    if prefer is not None and rows.size > 1:
        px = (prefer[0] - ox) / cell
        py = (prefer[1] * aspect - oy) / cell
        k = int(np.argmin((cols - px) ** 2 + (rows - py) ** 2))
    else:
        k = 0
    r0, c0 = float(rows[k]), float(cols[k])
    half = best - 1.0  # pixel centres within chessboard distance best-1 are inside
    side = 2.0 * half * cell
    x0 = ox + (c0 - half) * cell
    y0p = oy + (r0 - half) * cell
    return Rect(x0, y0p / aspect, side, side / aspect)
