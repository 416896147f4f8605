"""Grid triangulation and the per-triangle local coordinates of the conformal term.

A grid of ``rows x cols`` cells has ``(rows + 1) x (cols + 1)`` vertices, numbered
row-major. Each cell is split along its top-left -> bottom-right diagonal into the
triangles (a, b, e) and (a, e, d), where a = top-left, b = top-right, d = bottom-left,
e = bottom-right. In pixel coordinates (y down) both are positively oriented.
"""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray


def grid_triangles(rows: int, cols: int) -> IntArray:
    """Vertex indices (2 * rows * cols, 3) of the grid's triangles, cell by cell."""
    r, c = np.mgrid[0:rows, 0:cols]
    a = (r * (cols + 1) + c).ravel()
    b = a + 1
    d = a + cols + 1
    e = d + 1
    tris = np.empty((rows * cols, 2, 3), dtype=np.intp)
    tris[:, 0] = np.stack([a, b, e], axis=1)
    tris[:, 1] = np.stack([a, e, d], axis=1)
    return tris.reshape(-1, 3)


def grid_edges(rows: int, cols: int) -> IntArray:
    """Undirected edges (E, 2) of the triangulated grid: horizontal, vertical, diagonal."""
    idx = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    h = np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1)
    v = np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], axis=1)
    g = np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()], axis=1)
    return np.concatenate([h, v, g]).astype(np.intp)


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Row-wise cross product of (..., 3) arrays (np.cross without its overhead)."""
    out: FloatArray = np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )
    return out


def unique_edges(pairs: IntArray, n_vertices: int) -> tuple[IntArray, IntArray, IntArray]:
    """Unique undirected edges of ``pairs`` (E, 2): edges (U, 2) sorted, the index of
    each pair's edge (E,), and how often each edge occurs (U,)."""
    lo = np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    hi = np.maximum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    keys, inverse, counts = np.unique(lo * n_vertices + hi, return_inverse=True, return_counts=True)
    edges = np.stack([keys // n_vertices, keys % n_vertices], axis=1).astype(np.intp)
    return edges, inverse.astype(np.intp), counts.astype(np.intp)


def triangle_normals(p: FloatArray) -> FloatArray:
    """Unit normals (T, 3) of 3D triangles ``p`` (T, 3, 3), facing the projector.

    Triangles that are positively oriented in the projector image have a cross
    product pointing away from the projector; the normal is its negation.
    """
    n = -cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        out: FloatArray = n / norm
    return out


def conformal_coords(p: FloatArray) -> FloatArray:
    """Local coordinates (alpha, beta) of each vertex in its triangle's own plane.

    For triangle ``p`` (T, 3, 3) and each role k (apex V1 = vertex k, V2 = k+1,
    V3 = k+2, cyclically), ``P1 = P2 + alpha (P3 - P2) + beta R90 (P3 - P2)`` where
    R90 rotates by 90 degrees about the normal facing the projector (paper eq. 2).

    Returns
    -------
    (T, 3, 2) array of (alpha, beta).
    """
    n = triangle_normals(p)
    out = np.empty((*p.shape[:2], 2))
    for k in range(3):
        p1, p2, p3 = p[:, k], p[:, (k + 1) % 3], p[:, (k + 2) % 3]
        e = p3 - p2
        d = p1 - p2
        ee = np.sum(e * e, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, k, 0] = np.sum(d * e, axis=1) / ee
            out[:, k, 1] = np.sum(d * cross(n, e), axis=1) / ee
    return out


def rot90_2d(v: FloatArray) -> FloatArray:
    """The 2D rotation matching :func:`conformal_coords` in content space (y down)."""
    return np.stack([v[..., 1], -v[..., 0]], axis=-1)


def grid_cells(positions: FloatArray, n: int, step: int = 1) -> tuple[IntArray, FloatArray]:
    """The interval of increasing ``positions`` that each of 0..n-1 (every ``step``-th)
    falls in.

    Parameters
    ----------
    positions : (m,) float array, m >= 2
        Increasing coordinates of grid lines (pixel columns, vertex indices, ...).
    n : int
        The coordinates 0, 1, ..., n - 1 to place.
    step : int
        Place only every ``step``-th of them (0, step, 2 step, ...).

    Returns
    -------
    cell : (ceil(n / step),) int array
        Index ``c`` of the interval ``[positions[c], positions[c + 1]]`` (clamped to the
        first and last interval outside the range).
    fraction : (ceil(n / step),) float array
        Where in it: ``(x - positions[c]) / (positions[c + 1] - positions[c])``.
    """
    x = np.arange(0, n, step, dtype=np.float64)
    c = np.clip(np.searchsorted(positions, x, side="right") - 1, 0, positions.size - 2)
    f = (x - positions[c]) / (positions[c + 1] - positions[c])
    return c, f
