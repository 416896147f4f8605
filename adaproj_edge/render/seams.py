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

Inside a triangle the plane is a chord of the surface: projected onto it, a point of
a bent surface lands short of where the surface's development puts it (by the cell's
turn squared: on a cone turning away, 0.1 across a cell, 1.3 % of size). So where the
surface bends (:data:`BENT`) a pixel is placed from its distances to the triangle's
corners as the development measures them - each chord lengthened by what the normals
at its ends, the corner's and the pixel's own, say the surface bows out
(:func:`bow`: the curve under the chord a cubic with those end slopes, to fourth
order) - in the triangle whose sides are measured the same way. On a plane this is the
orthogonal projection, and two neighbours agree on their shared edge to third order
rather than second. The pixel's own normal matters where the curvature changes across
a cell: a wavy wall seen rolled, its rulings oblique, is split both ways to the vertex
budget and its cells span a sixth of a wave; placed as on an arc of constant curvature
from the corner, the pixels missed the crests and troughs (mean angle 1.3e-3 rolled 60
deg, 2.1e-3 at 45; 3.5e-4 and 4.8e-4 with the pixel's normal). In a triangle where a
pixel has no normal (a kink: a crease its corners do not show) the pixels' normals are
not used.

Weights are returned on six vertices per pixel: the three corners of its triangle and
the far corner of each neighbour across its edges.
"""

from __future__ import annotations

from dataclasses import dataclass

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
# a triangle whose corners' normals lean out of its plane by more than this (the sine)
# is placed on its development; within it the chord is exact to 1e-5 of a side
BENT = 0.005
# ... and by less than this (a corner on a crease or a silhouette has no one normal; a
# wavy wall rolled 45 deg, its cells a sixth of a wave, leans up to ~0.4: at 0.3 the
# triangles over its flanks were projected, mean angle 9.5e-4, 4.8e-4 with them placed)
BENT_MOST = 0.6
# the sine of the turn between the surface's steps either side of a vertex above which
# it is a kink (a crease through the vertex), not a bend: a corner of 150 deg turns 0.5;
# the wide cone rolled 90 deg, seen near grazing, turns by more than 0.03 in a pixel
# (size 8.1e-5 at 0.1, 3.3e-4 at 0.03)
KINK = 0.1


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


@dataclass(frozen=True)
class _Frames:
    """What places a surface point in each (unfolded) triangle (T of them): the (T, 2, 3)
    matrix ``plane`` and (T, 2) ``offset`` that give the barycentric weights of corners 1
    and 2 of its orthogonal projection onto the triangle's plane; whether the triangle
    is ``bent`` (T,), and for those its development's: corner 0 ``origin`` (T, 3), the
    edges to corners 1 and 2 ``edges`` (T, 2, 3), the corners' unit normals ``normals``
    (T, 3, 3) and their leans ``lean`` (T, 2) (``normals[:, k] . edges[:, k - 1]``), the
    edges' squared lengths ``sq`` (T, 2), and ``to_bary`` (T, 2, 2), ``bary_0`` (T, 2)
    that turn differences of squared distances into barycentric weights
    (:func:`_project`)."""

    plane: FloatArray
    offset: FloatArray
    bent: BoolArray
    origin: FloatArray
    edges: FloatArray
    normals: FloatArray
    lean: FloatArray
    sq: FloatArray
    to_bary: FloatArray
    bary_0: FloatArray


def _frames(unfolding: Unfolding, vertex_normals: FloatArray | None, corners: IntArray) -> _Frames:
    """The :class:`_Frames` of the (unfolded) triangles: their planes, and where the
    surface bends across one (its corners' ``vertex_normals`` (V, 3) lean out of its
    plane by between :data:`BENT` and :data:`BENT_MOST`; none given: nowhere), its
    development's."""
    pts = unfolding.points
    origin = pts[:, 0]
    a = np.stack([pts[:, 1] - origin, pts[:, 2] - origin], axis=1)  # (T, 2, 3)
    n = np.zeros_like(pts)
    bent = np.zeros(len(pts), dtype=bool)
    if vertex_normals is not None:
        nv = vertex_normals[corners]  # (T, 3, 3)
        sides = np.stack([a[:, 0], a[:, 1], a[:, 1] - a[:, 0]], axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            lean = (
                np.abs(np.einsum("tkj,tij->tki", nv, sides))
                / np.linalg.norm(sides, axis=2)[:, None, :]
            )
            most = np.max(np.where(np.isfinite(lean), lean, np.inf), axis=(1, 2))
            bent = ~unfolding.folded & (most > BENT) & (most < BENT_MOST)
        n[bent] = nv[bent]
    sq = np.sum(a * a, axis=2)  # (T, 2)

    def developed(e: FloatArray, na: FloatArray, nb: FloatArray) -> FloatArray:
        return np.asarray(
            np.sum(e * e, axis=1) + bow(np.sum(na * e, axis=1), np.sum(nb * e, axis=1))
        )

    g01 = developed(a[:, 0], n[:, 0], n[:, 1])
    g02 = developed(a[:, 1], n[:, 0], n[:, 2])
    g12 = developed(a[:, 1] - a[:, 0], n[:, 1], n[:, 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        # the developed triangle: corner 0 at 0, corner 1 at (x1, 0), corner 2 at (x2, y2);
        # a point q with squared distances D_k to the corners has 2 c_k . q = D_0 - D_k +
        # |c_k|^2 (k = 1, 2), and barycentric weights inv([c_1 c_2]) q
        x1 = np.sqrt(g01)
        x2 = (g01 + g02 - g12) / (2 * x1)
        y2 = np.sqrt(np.maximum(g02 - x2 * x2, 0.0))
        to_bary = np.zeros((x1.size, 2, 2))
        to_bary[:, 0, 0] = 1.0 / (2 * x1 * x1) + x2 * x2 / (2 * x1 * x1 * y2 * y2)
        to_bary[:, 0, 1] = -x2 / (2 * x1 * y2 * y2)
        to_bary[:, 1, 0] = -x2 / (2 * x1 * y2 * y2)
        to_bary[:, 1, 1] = 1.0 / (2 * y2 * y2)
    bary_0 = np.einsum("tij,tj->ti", to_bary, np.stack([g01, g02], axis=1))
    lean_nb = np.stack([np.sum(n[:, 1] * a[:, 0], axis=1), np.sum(n[:, 2] * a[:, 1], axis=1)], 1)
    plane, offset = _planes(unfolding)
    return _Frames(plane, offset, bent, origin, a, n, lean_nb, sq, to_bary, bary_0)


def bow(p: FloatArray, q: FloatArray) -> FloatArray:
    """What a chord ``d`` of a surface gains in squared length on the development:
    ``|d|^2 + bow(n_a . d, n_b . d)`` for the unit normals ``n_a``, ``n_b`` at its ends,
    the curve under it taken as a cubic with the slopes those normals give (``(2 p^2 +
    2 q^2 - p q) / 15``, to fourth order in the slopes; an arc of constant curvature,
    ``q = -p``, gives ``p^2 / 3``)."""
    out: FloatArray = (2 * p * p + 2 * q * q - p * q) / 15
    return out


def _planes(unfolding: Unfolding) -> tuple[FloatArray, FloatArray]:
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


def _project(
    t: IntArray,
    Xu: FloatArray,
    frames: _Frames,
    normals: FloatArray | None = None,
    kinked: BoolArray | None = None,
) -> FloatArray:
    """Barycentric weights (..., 3) on the corners of triangles ``t`` (...) of the
    (unfolded) surface points ``Xu`` (..., 3): projected onto each triangle's plane, or
    where it is bent (:func:`_frames`) placed from their developed squared distances to
    its corners (:func:`bow`, with the points' own unit ``normals`` (..., 3) where
    given and finite and the triangle is not ``kinked`` (T,); else as an arc of
    constant curvature from the corner)."""
    shape = t.shape
    t = t.reshape(-1)
    Xu = Xu.reshape(-1, 3)
    uv = np.einsum("nij,nj->ni", frames.plane[t], Xu) - frames.offset[t]
    on = frames.bent[t]
    if np.any(on):
        sel: slice | IntArray = slice(None) if np.all(on) else np.flatnonzero(on)
        tb = t[sel]
        y = Xu[sel] - frames.origin[tb]
        edges = frames.edges[tb]  # (n, 2, 3)
        ya = np.einsum("nkj,nj->nk", edges, y)  # (n, 2)
        p = np.einsum("nkj,nj->nk", frames.normals[tb], y)  # (n, 3): n_k . y
        p[:, 1:] -= frames.lean[tb]  # n_k . (y - a_k), a_0 = 0
        if normals is None:
            q = -p
        else:
            nx = normals.reshape(-1, 3)[sel]
            q = np.empty_like(p)  # n_x . (y - a_k)
            q[:, 0] = np.einsum("nj,nj->n", nx, y)
            q[:, 1:] = q[:, :1] - np.einsum("nkj,nj->nk", edges, nx)
            unknown = ~np.isfinite(q)
            if kinked is not None:
                unknown |= kinked[tb][:, None]
            q[unknown] = -p[unknown]
        gain = bow(p, q)
        # D_0 - D_k, D_k = |y - a_k|^2 + gain_k
        r = 2 * ya - frames.sq[tb] + gain[:, :1] - gain[:, 1:]
        uv[sel] = np.einsum("nij,nj->ni", frames.to_bary[tb], r) + frames.bary_0[tb]
    out = np.empty((t.size, 3))
    out[:, 0] = 1.0 - uv.sum(axis=1)
    out[:, 1:] = uv
    return out.reshape(*shape, 3)


def vertex_normals(surface: Surface, grid_uv: FloatArray, step: float = 1.0) -> FloatArray:
    """Unit normals (R * C, 3) of ``surface`` at the vertices ``grid_uv`` (R, C, 2), from
    its points ``step`` pixels either side (one side where the other has none); NaN
    where neither has, and at a kink (a crease: the two sides turn by more than
    :data:`KINK`), where the surface has no one normal."""
    uv = grid_uv.reshape(-1, 2)
    here = surface.points_at(uv).astype(np.float64)

    def at(axis: int, sign: float) -> FloatArray:
        d = np.zeros(2)
        d[axis] = sign * step
        out: FloatArray = surface.points_at(uv + d).astype(np.float64)
        return out

    return _normals(here, at(0, 1), at(0, -1), at(1, 1), at(1, -1))


def _normals(
    here: FloatArray,
    x_ahead: FloatArray,
    x_behind: FloatArray,
    y_ahead: FloatArray,
    y_behind: FloatArray,
) -> FloatArray:
    """Unit normals (..., 3) at the points ``here`` (..., 3) from their neighbours a
    step ahead and behind along x and y (..., 3 each, NaN where none):
    :func:`vertex_normals`."""
    kinked = np.zeros(here.shape[:-1], dtype=bool)

    def tangent(ahead: FloatArray, behind: FloatArray) -> FloatArray:
        ahead = ahead - here
        behind = here - behind
        with np.errstate(invalid="ignore", divide="ignore"):
            turn = np.linalg.norm(np.cross(ahead, behind), axis=-1) / (
                np.linalg.norm(ahead, axis=-1) * np.linalg.norm(behind, axis=-1)
            )
        kinked[turn > KINK] = True
        t = ahead + behind
        t = np.where(np.isfinite(t), t, ahead)
        out: FloatArray = np.where(np.isfinite(t), t, behind)
        return out

    n = np.cross(tangent(x_ahead, x_behind), tangent(y_ahead, y_behind))
    n[kinked] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        out: FloatArray = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return out


def _pixel_normals(
    surface: Surface,
    projector: Projector,
    X: FloatArray,
    tri: IntArray,
    bent: BoolArray,
    dense: bool,
) -> FloatArray:
    """Unit normals (H, W, 3) of the surface at the pixels' points ``X`` (H, W, 3)
    (:func:`vertex_normals` at the pixels they are seen at; ``dense``: ``X`` is every
    pixel's, its neighbours are those of the frame) where the pixel's triangle ``tri``
    (H, W) is ``bent`` (T,); NaN elsewhere and at a kink."""
    out = np.full(X.shape, np.nan)
    at = bent[tri] & np.isfinite(X).all(axis=-1)
    if not np.any(at):
        return out
    if dense:
        pad = np.full((X.shape[0] + 2, X.shape[1] + 2, 3), np.nan)
        pad[1:-1, 1:-1] = X
        n = _normals(X, pad[1:-1, 2:], pad[1:-1, :-2], pad[2:, 1:-1], pad[:-2, 1:-1])
        out[at] = n[at]
    else:
        out[at] = vertex_normals(surface, projector.project(X[at]))
    return out


def _kinked(tri: IntArray, normals: FloatArray, bent: BoolArray) -> BoolArray:
    """(T,): the ``bent`` triangles in which a pixel of ``tri`` (H, W) has no normal
    (``normals`` (H, W, 3) from :func:`_pixel_normals`): a kink, a crease running
    through that its corners do not show. There the surface between a corner and a
    pixel beyond the crease is no cubic, and the pixels' normals are not used (by the
    triangle's own pixels and by its neighbours' in its frame alike, so that the places
    blended across its edges are the same either side)."""
    out = np.zeros(bent.size, dtype=bool)
    none = bent[tri] & ~np.isfinite(normals).all(axis=-1)
    out[tri[none]] = True
    return out


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
    if unfolding is None:
        unfolding = grid_unfolding(grid_uv, depth, projector, surface)
    frames = _frames(unfolding, vertex_normals(surface, grid_uv), corners)
    X = (surface.dense().points if points is None else points).astype(np.float64)
    X_own = unfolding.unfold_points(tri, X)
    normals = triangle_normals(unfolding.points)
    nX = _pixel_normals(surface, projector, X, tri, frames.bent, points is None)
    kinked = _kinked(tri, nX, frames.bent)
    own = _project(tri, X_own, frames, nX, kinked)  # (H, W, 3)
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
            t_nb,
            _in_frame_of(tri[idx], t_nb, X[idx], X_own[idx], unfolding, normals),
            frames,
            nX[idx],
            kinked,
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
