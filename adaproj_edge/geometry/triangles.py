"""Grid triangulation and the per-triangle local coordinates of the conformal term.

A grid of ``rows x cols`` cells has ``(rows + 1) x (cols + 1)`` vertices, numbered
row-major. Each cell is split along its top-left -> bottom-right diagonal into the
triangles (a, b, e) and (a, e, d), where a = top-left, b = top-right, d = bottom-left,
e = bottom-right. In pixel coordinates (y down) both are positively oriented.
"""

from __future__ import annotations

import functools

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray


def grid_triangles(rows: int, cols: int) -> IntArray:
    """Vertex indices (2 * rows * cols, 3) of the grid's triangles, cell by cell
    (read-only: made once per grid size)."""
    return _grid_triangles(int(rows), int(cols))


@functools.lru_cache(maxsize=16)
def _grid_triangles(rows: int, cols: int) -> IntArray:
    r, c = np.mgrid[0:rows, 0:cols]
    a = (r * (cols + 1) + c).ravel()
    b = a + 1
    d = a + cols + 1
    e = d + 1
    tris = np.empty((rows * cols, 2, 3), dtype=np.intp)
    tris[:, 0] = np.stack([a, b, e], axis=1)
    tris[:, 1] = np.stack([a, e, d], axis=1)
    out = tris.reshape(-1, 3)
    out.flags.writeable = False
    return out


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
    return triangle_shapes(p)[0]


def triangle_shapes(p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """What the warp needs of the shapes of triangles ``p`` (T, 3, 3), at once.

    Returns
    -------
    coords : (T, 3, 2) the :func:`conformal_coords`.
    sides : (T, 3) side lengths, side k from corner k to corner k + 1.
    planar : (T, 3, 2) each triangle in a 2D frame of its own plane: corner 0 at the
        origin, corner 1 on the +x axis, corner 2 at y >= 0.
    """
    coords, sides, planar = shapes_first(corners_first(p))
    return coords, sides.T, planar


def corners_first(p: FloatArray) -> FloatArray:
    """Triangles (T, 3, 3) as component-first planes (xyz, corner, T), contiguous.

    The ``*_first`` functions work on these: each of their sums over the components
    adds x, y and z in that order, as ``np.sum`` over a (..., 3) axis does, so they give
    the same values as the (T, 3, 3) functions at a fraction of the cost.
    """
    out: FloatArray = np.ascontiguousarray(np.asarray(p, np.float64).transpose(2, 1, 0))
    return out


def planes_first(q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit normals (3, T) facing the projector (as :func:`triangle_normals`) and twice
    the areas (T,) of component-first triangles ``q`` (3, 3, T)."""
    n = -cross_first(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        area2: FloatArray = np.sqrt(dot_first(n, n))
        unit: FloatArray = n / area2
    return unit, area2


def shapes_first(
    q: FloatArray, normals: FloatArray | None = None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`triangle_shapes` of component-first triangles ``q`` (3, 3, T), with the
    side lengths component-first too (3, T); ``normals`` (3, T): their
    :func:`planes_first` normals, when the caller has them."""
    t = q.shape[2]
    e1, e2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    following = q[:, [1, 2, 0]]
    e = q[:, [2, 0, 1]] - following  # role k: P3 - P2
    d = q - following  # role k: P1 - P2
    side = following - q  # corner k + 1 - corner k: a side's length either way round
    n = planes_first(q)[0] if normals is None else normals
    with np.errstate(invalid="ignore", divide="ignore"):
        ee = dot_first(e, e)
        coords = np.empty((t, 3, 2))
        coords[:, :, 0] = (dot_first(d, e) / ee).T
        coords[:, :, 1] = (dot_first(d, cross_first(n[:, None], e)) / ee).T
        l1 = np.sqrt(dot_first(e1, e1))
        x2 = dot_first(e1, e2) / l1
    planar = np.zeros((t, 3, 2))
    planar[:, 1, 0] = l1
    planar[:, 2, 0] = x2
    planar[:, 2, 1] = np.sqrt(np.maximum(dot_first(e2, e2) - x2 * x2, 0.0))
    sides: FloatArray = np.sqrt(dot_first(side, side))
    return coords, sides, planar


def shapes_from_sides(sides: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The :func:`conformal_coords` (T, 3, 2) and planar shapes (T, 3, 2) (as
    :func:`triangle_shapes`) of triangles given by their side lengths ``sides`` (3, T)
    (side k from corner k to corner k + 1, component-first as :func:`shapes_first`'s);
    NaN where the three lengths make no triangle."""
    l1, l2, l3 = sides
    with np.errstate(invalid="ignore", divide="ignore"):
        x2 = (l1 * l1 + l3 * l3 - l2 * l2) / (2 * l1)
        y2 = np.sqrt(l3 * l3 - x2 * x2)
    t = sides.shape[1]
    q = np.zeros((3, 3, t))  # the shape in the plane z = 0, component-first
    q[0, 1] = l1
    q[0, 2], q[1, 2] = x2, y2
    # the shape's normal facing the projector, as planes_first's for a plane seen from
    # -z: corner 2 at y >= 0 turns it so
    normals = np.zeros((3, t))
    normals[2] = -1.0
    coords, _, planar = shapes_first(q, normals)
    return coords, planar


def dot_first(a: FloatArray, b: FloatArray) -> FloatArray:
    """Dot products of component-first (3, ...) arrays, x + y + z in that order."""
    out: FloatArray = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    return out


def cross_first(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross products of component-first (3, ...) arrays (as :func:`cross`)."""
    out: FloatArray = np.stack(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )
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


def carry_through_triangles(
    q: FloatArray, g: FloatArray, xy: FloatArray, slack: float = 1e-6
) -> FloatArray:
    """Points ``xy`` (N, 2) carried from triangles ``q`` (T, 3, 2) to triangles ``g``
    (T, 3, 2) corner for corner (each triangle linear; the first triangle of ``q`` that
    holds a point, its box widened by ``slack`` so that a point on an edge is held),
    NaN where none holds it (a NaN corner holds none): (N, 2)."""
    out: FloatArray = np.full((len(xy), 2), np.nan)
    # the pairs whose triangle's box holds the point (a NaN corner holds none), in
    # triangle order; then barycentric coordinates for those pairs alone
    c0, c1, c2 = q[:, 0], q[:, 1], q[:, 2]  # (three corners: not a slow reduce over 3)
    lo = np.minimum(np.minimum(c0, c1), c2) - slack  # (T, 2); NaN propagates
    hi = np.maximum(np.maximum(c0, c1), c2) + slack
    near = (
        (xy[None, :, 0] >= lo[:, None, 0])
        & (xy[None, :, 0] <= hi[:, None, 0])
        & (xy[None, :, 1] >= lo[:, None, 1])
        & (xy[None, :, 1] <= hi[:, None, 1])
    )
    ti, ni = np.nonzero(near)
    a = c0[ti]
    v0, v1 = c1[ti] - a, c2[ti] - a
    det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    d = xy[ni] - a
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (d[:, 0] * v1[:, 1] - d[:, 1] * v1[:, 0]) / det
        t = (v0[:, 0] * d[:, 1] - v0[:, 1] * d[:, 0]) / det
    inside = (s >= -1e-9) & (t >= -1e-9) & (s + t <= 1 + 1e-9) & np.isfinite(s + t)
    # the first triangle holding each point
    points, first = np.unique(ni[inside], return_index=True)
    k = np.flatnonzero(inside)[first]
    gk = g[ti[k]]  # (M, 3, 2)
    sk, tk = s[k, None], t[k, None]
    out[points] = gk[:, 0] + sk * (gk[:, 1] - gk[:, 0]) + tk * (gk[:, 2] - gk[:, 0])
    return out
