"""A coarse grid inside a fine one, and fields carried from the coarse to the fine.

The device refines the content-aware warp on a grid about ``factor`` times coarser than
the content-free one; its vertices are a subset of the fine grid's, so what the coarse
solve changes can be interpolated back onto every fine vertex
(:func:`upsample_field`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.triangles import grid_cells


def coarse_indices(cells: int, factor: int) -> IntArray:
    """Fine-grid vertex indices of a grid about ``factor`` times coarser.

    Parameters
    ----------
    cells : int
        Cells of the fine grid along one axis (vertices 0..cells).
    factor : int
        How many times coarser (1: every fine vertex).

    Returns
    -------
    (m + 1,) int array
        Increasing fine vertex indices, both ends included, at least 2 cells.
    """
    m = max(2, -(-cells // max(factor, 1)))
    return np.unique(np.rint(np.linspace(0, cells, min(m, cells) + 1)).astype(np.intp))


def linear_weights(coarse: IntArray, n: int) -> FloatArray:
    """(n, len(coarse)) weights interpolating values at the ``coarse`` indices linearly
    to every index 0..n-1."""
    j, f = grid_cells(coarse.astype(np.float64), n)
    W = np.zeros((n, coarse.size))
    W[np.arange(n), j] = 1.0 - f
    W[np.arange(n), j + 1] += f
    return W


def upsample_field(
    values: FloatArray, rows: IntArray, cols: IntArray, shape: tuple[int, int]
) -> FloatArray:
    """Values at the coarse vertices interpolated bilinearly to every fine vertex.

    Parameters
    ----------
    values : (r, c, k) float array
        Values at the coarse vertices ``rows`` x ``cols``; unknown (NaN) ones take the
        nearest known value first.
    rows, cols : (r,), (c,) int arrays
        The coarse vertices' fine indices (:func:`coarse_indices`).
    shape : (R, C)
        The fine grid's vertex counts.

    Returns
    -------
    (R, C, k) float array
        Zeros when no coarse value is known.
    """
    known = np.isfinite(values).all(axis=-1)
    if not known.any():
        return np.zeros((*shape, values.shape[-1]))
    if not known.all():
        idx = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
        values = values[idx[0], idx[1]]
    Wr = linear_weights(rows, shape[0])
    Wc = linear_weights(cols, shape[1])
    # rows then columns (one three-operand einsum sums in the worst order: 10x slower)
    along_rows = np.einsum("ir,rck->ick", Wr, values)
    out: FloatArray = np.einsum("ick,jc->ijk", along_rows, Wc)
    return out


def coarse_cells_of(
    fine_tris: IntArray, fine_cols: int, rows: IntArray, cols: IntArray
) -> NDArray[np.bool_]:
    """Which triangles of the coarse grid on fine vertex ``rows`` x ``cols`` (2 per
    cell, :func:`~adaproj_edge.geometry.triangles.grid_triangles` order) lie in a coarse
    cell holding, or next to one holding, one of the fine grid's triangles
    ``fine_tris`` (indices in that order on a grid of ``fine_cols`` cells a row)."""
    cell = np.asarray(fine_tris) // 2
    r = np.searchsorted(rows, cell // fine_cols, side="right") - 1
    c = np.searchsorted(cols, cell % fine_cols, side="right") - 1
    near = np.zeros((rows.size - 1, cols.size - 1), dtype=bool)
    inside = (r >= 0) & (r < near.shape[0]) & (c >= 0) & (c < near.shape[1])
    near[r[inside], c[inside]] = True
    near = ndimage.binary_dilation(near, structure=np.ones((3, 3), dtype=bool))
    return np.repeat(near.ravel(), 2)


def filled_by_shapes(v: FloatArray, tris: IntArray, coords: FloatArray) -> FloatArray | None:
    """Positions ``v`` (n, 2) with their NaN rows filled from the triangles around them:
    a triangle (``tris`` (T, 3)) with two corners known places its third where its
    shape on the surface puts it (its conformal ``coords`` (T, 3, 2), eq. 4 of the
    paper: ``V1 = V2 + alpha (V3 - V2) + beta R90 (V3 - V2)``, ``R90`` a multiplication
    by ``-i``), the mean of the triangles that place a vertex in the same round; round
    after round from the known ones outward. None when no chain of triangles reaches
    some vertex.

    The device's coarse mesh may hold a vertex the fine mesh has not (on sensed depth, at
    a hole's edge the coarse triangles bridge): its start fills it so, in the place the
    content-free warp's similarity would put it, without a solve of its own."""
    z = v[:, 0] + 1j * v[:, 1]
    known = np.isfinite(z)
    if known.all():
        return v
    if not known.any():
        return None
    coef = coords[..., 0] - 1j * coords[..., 1]  # (T, 3): role k's alpha - i beta
    while True:  # (each round places a vertex at least, or ends)
        at = known[tris]  # (T, 3)
        total = np.zeros(z.size, dtype=np.complex128)
        count = np.zeros(z.size)
        for k in range(3):
            k1, k2 = (k + 1) % 3, (k + 2) % 3
            sel = np.flatnonzero(~at[:, k] & at[:, k1] & at[:, k2])
            if sel.size == 0:
                continue
            p2, p3 = z[tris[sel, k1]], z[tris[sel, k2]]
            guess = p2 + coef[sel, k] * (p3 - p2)
            ok = np.isfinite(guess)
            np.add.at(total, tris[sel[ok], k], guess[ok])
            np.add.at(count, tris[sel[ok], k], 1.0)
        new = np.flatnonzero(count > 0)
        if new.size == 0:
            return None
        z[new] = total[new] / count[new]
        known[new] = True
        if known.all():
            return np.stack([z.real, z.imag], axis=1)
