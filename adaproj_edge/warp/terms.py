"""Residual rows of the warp energies (paper §3.2–3.3, §4), built from COO-like arrays.

Unknowns are laid out per mesh vertex k: ``x = stride*k``, ``y = stride*k + 1`` and,
when the relative-size term is present (stride 3), the auxiliary scale
``s = stride*k + 2``. Every function returns a :class:`Rows` block; the engine gives
each row its weight.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.warp.system import Rows


def conformal_rows(tris: IntArray, coords: FloatArray, stride: int) -> Rows:
    """E_a (eq. 4): for each triangle (T, 3) and each of its vertices as apex V1,
    ``V1 - V2 - alpha (V3 - V2) - beta R90 (V3 - V2)``, two rows (x, y).

    Rows are ordered (triangle, role, component); (6T, 5) coefficients.
    """
    t = tris.shape[0]
    cols = np.empty((t, 3, 2, 5), dtype=np.intp)
    vals = np.empty((t, 3, 2, 5))
    for k in range(3):
        i1, i2, i3 = tris[:, k], tris[:, (k + 1) % 3], tris[:, (k + 2) % 3]
        a = coords[:, k, 0]
        b = coords[:, k, 1]
        x1, x2, x3 = stride * i1, stride * i2, stride * i3
        y1, y2, y3 = x1 + 1, x2 + 1, x3 + 1
        one = np.ones(t)
        # r_x = x1 - (1-a) x2 - a x3 + b y2 - b y3
        cols[:, k, 0] = np.stack([x1, x2, x3, y2, y3], axis=1)
        vals[:, k, 0] = np.stack([one, a - 1, -a, b, -b], axis=1)
        # r_y = y1 - (1-a) y2 - a y3 - b x2 + b x3
        cols[:, k, 1] = np.stack([y1, y2, y3, x2, x3], axis=1)
        vals[:, k, 1] = np.stack([one, a - 1, -a, -b, b], axis=1)
    return Rows(cols.reshape(-1, 5), vals.reshape(-1, 5), np.zeros(6 * t))


def scale_edge_rows(
    edges: IntArray, lengths: FloatArray, directions: FloatArray, stride: int = 3
) -> Rows:
    """r(V_i, s_i) (eq. 11): for each directed edge i -> j,
    ``V_i - V_j - s_i l_ij v_ij``, two rows (x, y); (2E, 3) coefficients.

    ``edges`` (E, 2) directed, ``lengths`` (E,) on the surface, ``directions`` (E, 2)
    unit vectors in content space.
    """
    i, j = edges[:, 0], edges[:, 1]
    e = edges.shape[0]
    cols = np.empty((e, 2, 3), dtype=np.intp)
    vals = np.empty((e, 2, 3))
    for c in range(2):
        cols[:, c] = np.stack([stride * i + c, stride * j + c, stride * i + 2], axis=1)
        vals[:, c, 0] = 1.0
        vals[:, c, 1] = -1.0
        vals[:, c, 2] = -lengths * directions[:, c]
    return Rows(cols.reshape(-1, 3), vals.reshape(-1, 3), np.zeros(2 * e))


def scale_smooth_rows(edges: IntArray, stride: int = 3) -> Rows:
    """``s_i - s_j`` for each undirected edge (eq. 10, first sum); (E, 2)."""
    cols = np.stack([stride * edges[:, 0] + 2, stride * edges[:, 1] + 2], axis=1)
    vals = np.tile(np.array([1.0, -1.0]), (edges.shape[0], 1))
    return Rows(cols.astype(np.intp), vals, np.zeros(edges.shape[0]))


def position_rows(n_vertices: int, stride: int) -> Rows:
    """``V_k - target`` rows (x then y per vertex); targets are set by the caller."""
    base = stride * np.arange(n_vertices)
    cols = np.stack([base, base + 1], axis=1).reshape(-1, 1).astype(np.intp)
    return Rows(cols, np.ones((2 * n_vertices, 1)), np.zeros(2 * n_vertices))


def edge_rows(edges: IntArray, stride: int = 2) -> Rows:
    """``V_i - V_j - l_ij v_ij`` for each undirected edge, two rows (x, y); the target
    ``l_ij v_ij`` goes in the right-hand side, set by the caller (:func:`set_edge_targets`)."""
    e = edges.shape[0]
    cols = np.empty((e, 2, 2), dtype=np.intp)
    for c in range(2):
        cols[:, c] = np.stack([stride * edges[:, 0] + c, stride * edges[:, 1] + c], axis=1)
    vals = np.tile(np.array([1.0, -1.0]), (2 * e, 1))
    return Rows(cols.reshape(-1, 2), vals, np.zeros(2 * e))


def edge_normal_rows(edges: IntArray, stride: int = 2) -> Rows:
    """``n_ij . (V_i - V_j)`` for each undirected edge, n_ij the normal of its target
    direction: the edge may change length, not direction. Coefficients are set by the
    caller (:func:`set_edge_normals`)."""
    i, j = edges[:, 0], edges[:, 1]
    cols = np.stack([stride * i, stride * i + 1, stride * j, stride * j + 1], axis=1)
    return Rows(cols.astype(np.intp), np.zeros((edges.shape[0], 4)), np.zeros(edges.shape[0]))


def complex_conformal_rows(
    tris: IntArray, coords: FloatArray
) -> tuple[IntArray, NDArray[np.complex128]]:
    """E_a (eq. 4) over complex unknowns ``z = x + i y`` (one per vertex): for each
    triangle (T, 3) and role, ``z1 + (alpha - 1 - i beta) z2 + (i beta - alpha) z3``
    (``R90`` is a multiplication by ``-i``). Rows ordered (triangle, role): (3T, 3)
    vertex indices and coefficients."""
    cols = np.empty((tris.shape[0], 3, 3), dtype=np.intp)
    vals = np.empty((tris.shape[0], 3, 3), dtype=np.complex128)
    for k in range(3):
        cols[:, k] = np.stack([tris[:, k], tris[:, (k + 1) % 3], tris[:, (k + 2) % 3]], axis=1)
        ab = coords[:, k, 0] + 1j * coords[:, k, 1]
        vals[:, k, 0] = 1.0
        vals[:, k, 1] = np.conj(ab) - 1.0
        vals[:, k, 2] = -np.conj(ab)
    return cols.reshape(-1, 3), vals.reshape(-1, 3)


def complex_edge_rows(edges: IntArray) -> tuple[IntArray, NDArray[np.complex128]]:
    """``z_i - z_j`` for each edge (E, 2): (E, 2) indices and coefficients."""
    vals = np.tile(np.array([1.0, -1.0], dtype=np.complex128), (edges.shape[0], 1))
    return edges.astype(np.intp), vals


def complex_position_rows(n_vertices: int) -> tuple[IntArray, NDArray[np.complex128]]:
    """``z_k`` for every vertex: (n, 1) indices and coefficients."""
    return np.arange(n_vertices, dtype=np.intp)[:, None], np.ones((n_vertices, 1), np.complex128)
