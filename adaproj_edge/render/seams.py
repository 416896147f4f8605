"""Per-pixel weights from the surface itself, continuous across the mesh's seams.

Each pixel's own surface point X, unfolded like its triangle where a crease runs
through it (:mod:`adaproj_edge.geometry.creases`), is projected orthogonally onto the
plane of the triangle: on a plane this is exact, on a curved developable surface the
error is second order in the cell's curvature. Each triangle has its own plane, so
two triangles sharing an edge place the pixels on it a little differently (on a
strongly curved surface or a curved crease, by a pixel or more): a seam the display
would show as a fold. So near an edge, within a band of a few pixels, a pixel is
placed by both triangles and the two places are blended, half and half on the edge
itself: the map is continuous there, and where both triangles are exact (a plane, a
straight crease) the blend is too.

Not across a crease that runs along the edge itself (two flat triangles whose planes
differ by more than a crease's angle, neither unfolded): each side is exact and the two
agree along the edge, while the neighbour's plane is the other wall's, onto which a
pixel's point would project wrongly (a kink a band wide along the crease).

Weights are returned on six vertices per pixel: the three corners of its triangle and
the far corner of each neighbour across its edges.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray, IntArray
from adaproj_edge.geometry.creases import CREASE_COS, Unfolding, unfold_creases
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import grid_triangles, triangle_normals

BAND = 12.0  # pixels either side of an edge where the two triangles' places are blended
# ... at most this share of the triangle's smallest height: on a refined grid's small
# cells the seam's kink (the two planes' places differ there by the cell's sag times its
# turn) is spread over this much of the triangle, and the map's Jacobian jumps by the
# kink over the band's width. The shares of the three edges sum to at most 1 for any
# share up to 1. 0.4 -> 0.7: the wide cone rolled 70 deg 8.3e-4 -> 4.7e-4 in mean angle;
# the device's 20x20 cells (smallest height 34 px) keep the 12 px band either way
BAND_SHARE = 0.7


def grid_neighbours(rows: int, cols: int) -> IntArray:
    """For each triangle of a ``rows`` x ``cols`` cell grid (``grid_triangles`` order),
    the triangle across the edge opposite each of its corners, -1 at the border: (T, 3).

    Upper triangles (a, b, e): right edge (b, e), diagonal (e, a), top edge (a, b);
    lower ones (a, e, d): bottom edge (e, d), left edge (d, a), diagonal (a, e).
    """
    r, c = np.mgrid[0:rows, 0:cols]
    cell = r * cols + c
    upper, lower = 2 * cell, 2 * cell + 1
    out = np.full((rows, cols, 2, 3), -1, dtype=np.intp)
    out[:, :-1, 0, 0] = lower[:, 1:]  # right: the next cell's lower triangle
    out[..., 0, 1] = lower  # diagonal
    out[1:, :, 0, 2] = lower[:-1, :]  # top: the cell above's lower triangle
    out[:-1, :, 1, 0] = upper[1:, :]  # bottom: the cell below's upper triangle
    out[:, 1:, 1, 1] = upper[:, :-1]  # left: the previous cell's upper triangle
    out[..., 1, 2] = upper  # diagonal
    return out.reshape(-1, 3)


def _planes(points: FloatArray, unfolding: Unfolding) -> tuple[FloatArray, FloatArray]:
    """For each (unfolded) triangle (T, 3, 3): the (T, 2, 3) matrix and (T, 2) offset that
    give the barycentric weights (u, v) of corners 1 and 2 of a point's orthogonal
    projection onto the triangle's plane."""
    pts = unfolding.points
    origin = pts[:, 0]
    e1 = pts[:, 1] - origin
    e2 = pts[:, 2] - origin
    with np.errstate(invalid="ignore", divide="ignore"):
        g11 = np.sum(e1 * e1, axis=1)[:, None]
        g12 = np.sum(e1 * e2, axis=1)[:, None]
        g22 = np.sum(e2 * e2, axis=1)[:, None]
        det = g11 * g22 - g12 * g12
        bary = np.stack([g22 * e1 - g12 * e2, g11 * e2 - g12 * e1], axis=1) / det[:, :, None]
    return bary, np.einsum("tij,tj->ti", bary, origin)


def _project(t: IntArray, Xu: FloatArray, bary: FloatArray, offset: FloatArray) -> FloatArray:
    """Barycentric weights (..., 3) on the corners of triangles ``t`` (...) of the
    (unfolded) surface points ``Xu`` (..., 3), projected onto each triangle's plane."""
    m = bary[t]
    uv = np.einsum("...ij,...j->...i", m, Xu) - offset[t]
    return np.concatenate([1.0 - uv.sum(axis=-1, keepdims=True), uv], axis=-1)


def _in_frame_of(
    own: IntArray,
    nb: IntArray,
    X: FloatArray,
    X_own: FloatArray,
    unfolding: Unfolding,
    normals: FloatArray,
) -> FloatArray:
    """Surface points ``X`` (N, 3) of triangles ``own`` (N,) (``X_own``: as they unfold
    them) in the frame of their neighbours ``nb`` (N,): unfolded by the neighbour when a
    crease runs through it; else, when a crease runs through the own triangle, in the
    plane of the crease's side the neighbour lies on."""
    out = X.copy()
    nb_folded = unfolding.folded[nb]
    out[nb_folded] = unfolding.unfold_points(nb[nb_folded], X[nb_folded])
    mine = unfolding.folded[own] & ~nb_folded
    if np.any(mine):
        t, n = own[mine], normals[nb[mine]]
        on_a = np.abs(np.sum(n * unfolding.normal_a[t], axis=1)) >= np.abs(
            np.sum(n * unfolding.normal_b[t], axis=1)
        )
        o = unfolding.origin[t]
        back = o + np.einsum("nji,nj->ni", unfolding.rotation[t], X_own[mine] - o)  # R^T
        out[mine] = np.where(on_a[:, None], X_own[mine], back)
    return out


def _blended_edges(neighbours: IntArray, unfolding: Unfolding, normals: FloatArray) -> BoolArray:
    """(T, 3): whether the places given by triangle t and its neighbour ``neighbours``
    (T, 3) across the edge opposite corner k are blended: there is a neighbour, and the
    edge is no crease (two flat triangles, neither unfolded, whose planes, unit
    ``normals`` (T, 3), differ by more than a crease's angle)."""
    nb = np.maximum(neighbours, 0)
    plain = unfolding.flat & ~unfolding.folded & np.isfinite(normals).all(axis=1)
    with np.errstate(invalid="ignore"):
        apart = np.einsum("tj,tkj->tk", normals, normals[nb]) < CREASE_COS
    crease = plain[:, None] & plain[nb] & apart
    out: BoolArray = np.asarray((neighbours >= 0) & ~crease, dtype=bool)
    return out


def grid_unfolding(
    grid_uv: FloatArray, depth: FloatArray, projector: Projector, surface: Surface
) -> Unfolding:
    """The creases of the grid's triangles (``grid_triangles`` order) unfolded
    (:func:`~adaproj_edge.geometry.creases.unfold_creases`); ``grid_uv`` (R, C, 2) and
    ``depth`` (R, C) as :func:`surface_weights` takes them."""
    rows, cols = grid_uv.shape[:2]
    corners = grid_triangles(rows - 1, cols - 1)
    P = (projector.rays(grid_uv) * depth[..., None]).reshape(-1, 3)
    return unfold_creases(surface, grid_uv.reshape(-1, 2)[corners], corners, P)


def surface_weights(
    grid_uv: FloatArray,
    depth: FloatArray,
    projector: Projector,
    surface: Surface,
    tri: IntArray,
    barycentric: FloatArray,
    points: FloatArray | None = None,
    unfolding: Unfolding | None = None,
) -> tuple[NDArray[np.int32], FloatArray]:
    """Seam-blended surface weights of every pixel (or of the pixels ``tri`` describes,
    given their ``points``).

    Parameters
    ----------
    grid_uv : (R, C, 2) vertex pixel positions.
    depth : (R, C) vertex depths (NaN without surface).
    projector : Projector
    surface : Surface
        Dense or lattice surface; each pixel's own point is taken from it.
    tri : (H, W) each pixel's triangle (``grid_triangles`` order).
    barycentric : (3, H, W) each pixel's pixel-space barycentric weights in it.
    points : (H, W, 3), optional
        Each pixel's own surface point; default: the dense surface (every pixel).
    unfolding : Unfolding, optional
        The grid triangles' :func:`grid_unfolding`, when the caller has it already.

    Returns
    -------
    corners : (6, H, W) int32 grid vertex indices (own corners, then the far corner
        of the neighbour across the edge opposite own corner 0, 1, 2).
    weights : (6, H, W) float64, NaN where the pixel's surface point is unknown.
    """
    rows, cols = grid_uv.shape[:2]
    corners = grid_triangles(rows - 1, cols - 1)
    neighbours = grid_neighbours(rows - 1, cols - 1)
    P = (projector.rays(grid_uv) * depth[..., None]).reshape(-1, 3)
    if unfolding is None:
        unfolding = grid_unfolding(grid_uv, depth, projector, surface)
    bary, offset = _planes(P, unfolding)
    X = (surface.dense().points if points is None else points).astype(np.float64)
    X_own = unfolding.unfold_points(tri, X)
    normals = triangle_normals(unfolding.points)
    own = _project(tri, X_own, bary, offset)  # (H, W, 3)
    has_depth = np.isfinite(depth.reshape(-1))
    tri_ok = np.asarray(has_depth[corners].all(axis=1), dtype=bool)
    # the band: pixel distance to each edge, from the pixel-space barycentrics
    uv = grid_uv.reshape(-1, 2)[corners]  # (T, 3, 2)
    area2 = np.abs(
        (uv[:, 1, 0] - uv[:, 0, 0]) * (uv[:, 2, 1] - uv[:, 0, 1])
        - (uv[:, 1, 1] - uv[:, 0, 1]) * (uv[:, 2, 0] - uv[:, 0, 0])
    )
    heights = np.stack(
        [area2 / np.linalg.norm(uv[:, (k + 2) % 3] - uv[:, (k + 1) % 3], axis=1) for k in range(3)],
        axis=1,
    )  # (T, 3): over the edge opposite corner k
    band = np.minimum(BAND, BAND_SHARE * heights.min(axis=1))
    seam = _blended_edges(neighbours, unfolding, normals)
    out_c = np.zeros((6, *tri.shape), dtype=np.int32)
    out_w = np.zeros((6, *tri.shape))
    pix_corners = corners[tri]  # (H, W, 3)
    out_c[:3] = np.moveaxis(pix_corners, -1, 0)
    out_c[3:] = out_c[0]  # unused slots (weight 0) point at a corner the pixel has
    share = np.zeros((3, *tri.shape))
    blend = np.zeros((6, *tri.shape))
    for k in range(3):
        nb = neighbours[tri, k]
        dist = barycentric[k] * heights[tri, k]
        b = band[tri]
        near: BoolArray = np.asarray((dist < b) & seam[tri, k], dtype=bool)
        near &= tri_ok[np.maximum(nb, 0)]
        idx = np.nonzero(near)
        if idx[0].size == 0:
            continue
        t_nb = nb[idx]
        w_nb = _project(
            t_nb, _in_frame_of(tri[idx], t_nb, X[idx], X_own[idx], unfolding, normals), bary, offset
        )  # (N, 3)
        good = np.all(np.isfinite(w_nb), axis=1)
        idx = (idx[0][good], idx[1][good])
        t_nb, w_nb = t_nb[good], w_nb[good]
        s = 0.5 * (1.0 - dist[idx] / b[idx]) ** 2
        share[k][idx] = s
        # the neighbour's corners in this pixel's slots: the edge's two own corners
        # (opposite corner k) and the neighbour's far corner
        nb_corners = corners[t_nb]
        own_c = pix_corners[idx]
        for j in range(3):
            cj = nb_corners[:, j]
            for slot in ((k + 1) % 3, (k + 2) % 3):
                hit = cj == own_c[:, slot]
                blend[slot][idx[0][hit], idx[1][hit]] += s[hit] * w_nb[hit, j]
            far = (cj != own_c[:, (k + 1) % 3]) & (cj != own_c[:, (k + 2) % 3])
            blend[3 + k][idx[0][far], idx[1][far]] += s[far] * w_nb[far, j]
            out_c[3 + k][idx[0][far], idx[1][far]] = cj[far]
    keep = 1.0 - share.sum(axis=0)
    for k in range(3):
        out_w[k] = keep * own[..., k] + blend[k]
        out_w[3 + k] = blend[3 + k]
    unknown = ~np.all(np.isfinite(own), axis=-1)
    out_w[:, unknown] = np.nan
    return out_c, out_w
