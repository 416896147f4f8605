"""Which way each triangle of a warp turns: a warp whose triangles keep the orientation
they have in the projector frame shows the content without folding it over."""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.triangles import grid_triangles
from adaproj_edge.warp.warpmap import Warp


def signed_areas(points: FloatArray, tris: IntArray) -> FloatArray:
    """Twice the signed area of each triangle.

    Parameters
    ----------
    points : (N, 2) float array
        Vertex positions (any 2D space).
    tris : (T, 3) int array
        Vertex indices of the triangles.

    Returns
    -------
    (T,) float array
        ``(p1 - p0) x (p2 - p0)``; positive for the grid's own orientation in pixel
        space (x right, y down), NaN where a corner is unknown.
    """
    q = np.take(points, tris.T, axis=0)  # (3, T, 2): per corner (gathers rows fast)
    a, b = q[1] - q[0], q[2] - q[0]
    out: FloatArray = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def unfolded(points: FloatArray, tris: IntArray) -> bool:
    """Whether no triangle of ``points`` (N, 2) over ``tris`` (T, 3) is folded over or
    degenerate (all keep the orientation they have in the projector frame)."""
    return bool(np.all(signed_areas(points, tris) > 0))


def fold_count(warp: Warp) -> int:
    """Grid triangles of ``warp`` (with all corners known) whose orientation in content
    space differs from the one they have in the projector frame."""
    rows, cols = warp.grid_uv.shape[:2]
    tris = grid_triangles(rows - 1, cols - 1)
    c = signed_areas(warp.image_xy.reshape(-1, 2), tris)
    ref = signed_areas(warp.grid_uv.reshape(-1, 2), tris)
    ok = np.isfinite(c)
    return int(np.sum(c[ok] * ref[ok] <= 0))
