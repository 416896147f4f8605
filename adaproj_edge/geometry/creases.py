"""Creases: unfolding grid triangles that a wall corner runs through.

A grid triangle whose surface (sampled at its edge midpoints and centroid) lies
farther than ``ROUGH`` of its size from its own plane has a crease in it: its chord
triangle cuts the corner and has the wrong shape. Each of its corners takes the plane
of the smooth triangles around it; when these are two different planes, the corners
on the second plane are rotated about the planes' line of intersection into the first
- the surface is unfolded there, exactly as it develops. The warp solve uses the
unfolded shapes, and the renderer unfolds each pixel's surface point the same way, so
both walls of a corner are exact up to the crease itself.

A crease that runs a hair past a grid vertex clips a sliver off the triangles there:
they lie within ``ROUGH`` of their plane, yet that plane is tilted. Triangles farther
than ``SLIGHT`` from their plane are looked at too (as straight creases only: their two
planes must explain them as a flat triangle's plane does), also where no triangle is
rough (a crease half a pixel past a grid line clips only slivers: left folded into one
plane, the display showed a kink along it), and a vertex takes its plane from its flat
triangles where it has any, so a sliver's tilt does not spoil its neighbours'
unfolding. A crease that runs along a grid line leaves flat triangles on either side
whose planes differ: :attr:`Unfolding.flat` says which triangles are flat, so the
display does not blend across such an edge (:mod:`adaproj_edge.render.seams`).

A wall seen grazing whose strip ends within the one column of cells the crease runs
through has no triangle of its own: its triangles are chords across the crease, so
large on the surface that the other wall's sliver leaves some of them within
``SLIGHT``. Such a flat triangle that is not ``PLANAR`` lends no plane to a vertex
whose flattest triangle's plane differs from its own by a crease's angle (the other
wall's, there) where the rest of it lies on one plane (a sliver at that corner), and is
a candidate; and a side none of whose corners has a planar
triangle, across from one whose corners have, takes the plane its own samples in the
triangle lie on (corners and probes nearer its plane than the other's).

A straight crease may have a curved side (a wall meeting a cone along a ruling): its
corners' planes are tangent to the cone a cell away, so the line they meet along is off
the crease, whether they explain its triangles (within ``FIT``, or as a curved crease)
or not. So where a side is curved (a corner of the triangle has no flat triangles) or
the corners' planes do not explain a rough triangle, each side is fitted with a
quadratic patch from its smooth triangles next to the crease
(:mod:`adaproj_edge.geometry.ruled_crease`); where the patches meet along a straight
line and explain the triangle to ``RULED_FIT`` of its size, it is unfolded about that
line with the patches' tangent planes there (a triangle its corners' planes explained
only if a patch is bent: two planes are the corners' own, a curved crease seen along
a ruling of its curved side, or a sliver at a corner). The patches are fitted only
next to a kink (a triangle at the candidate's corners whose probes are not a
quadratic's to ``KINK``): sensed depth smoothed across a jump is rough and its
corners' planes are far apart, yet it holds no crease for them to find. On sensed depth
snapped to two walls or more, a candidate across the line where two of them meet takes
their planes without a fit (:mod:`adaproj_edge.geometry.wall_crease`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.planes import plane_equations
from adaproj_edge.geometry.ruled_crease import pixel_spans, ruled_planes
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import corners_first, dot_first, planes_first
from adaproj_edge.geometry.wall_crease import wall_planes

ROUGH = 0.02  # surface-to-triangle distance, relative to the triangle's size, of a crease
SLIGHT = 1e-3  # ... of one it may clip a sliver off
PLANAR = 1e-4  # ... of a piece of one plane (float32 points: ~1e-6)
CREASE_COS = float(np.cos(np.deg2rad(5.0)))  # planes further apart than this make a crease
FIT = 0.25  # the two planes must explain the surface this much better than the triangle
CURVED_FIT = 0.2  # ... or, on a curved crease, this much better than its chord does
SAME_SIDE_COS = float(np.cos(np.deg2rad(12.0)))  # two corners of one side: nearly one plane
RULED_FIT = 1e-3  # a straight crease with curved sides: their patches explain them so
RULED_CREASE_COS = float(np.cos(np.deg2rad(10.0)))  # ... where its planes are this far apart
# ... and a triangle at its corners has a kink: a quadratic through that triangle's
# corners and edge midpoints misses its centroid by this much of its size
KINK = 1e-3
SOFTNESS = 4.0  # on a curved crease, the side is chosen softly over this many fit residuals


@dataclass(frozen=True)
class Unfolding:
    """Triangle corners with creases unfolded, and how to unfold a point of each triangle.

    Attributes
    ----------
    points : (T, 3, 3) corners, unfolded where ``folded``.
    folded : (T,) bool.
    normal_a, normal_b : (T, 3) the two planes' normals (NaN where not folded).
    point_b : (T, 3) a point of plane b.
    rotation : (T, 3, 3) and origin : (T, 3): a point X of plane b unfolds to
        ``origin + rotation @ (X - origin)``.
    softness : (T,) metres over which the side of a point is blended (0: a straight
        crease, the nearer plane's side).
    ruled : (T,) bool, unfolded about a straight crease between curved sides (the
        planes are the sides' patches' tangent planes there, not the corners').
    flat : (T,) bool, the surface at its probes lies within ``SLIGHT`` of its size
        from its (chord) plane: the triangle is a piece of one plane. Two flat
        triangles whose planes differ by more than a crease's angle meet along a crease
        that runs along their common edge.
    """

    points: FloatArray
    folded: NDArray[np.bool_]
    normal_a: FloatArray
    point_a: FloatArray
    normal_b: FloatArray
    point_b: FloatArray
    rotation: FloatArray
    origin: FloatArray
    softness: FloatArray
    ruled: NDArray[np.bool_]
    flat: NDArray[np.bool_]

    def unfold_points(self, t: IntArray, X: FloatArray) -> FloatArray:
        """Unfold surface points ``X`` (..., 3) lying in triangles ``t`` (...).

        A point nearer plane b than plane a is rotated with it. At a curved crease the
        two planes meet along a line that is not the crease, so a hard choice would tear
        the map where the surface changes side; there the choice is blended over the
        triangle's ``softness`` (metres of difference in the distances to the planes).
        """
        out = X.copy()
        f = self.folded[t]
        if not np.any(f):
            return out
        tf, xf = t[f], X[f]
        da = np.abs(np.sum((xf - self.point_a[tf]) * self.normal_a[tf], axis=-1))
        db = np.abs(np.sum((xf - self.point_b[tf]) * self.normal_b[tf], axis=-1))
        soft = self.softness[tf]
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(soft > 0, np.clip(0.5 + (da - db) / (2 * soft), 0.0, 1.0), 0.0)
        share = np.where(soft > 0, s * s * (3 - 2 * s), (db < da).astype(np.float64))
        o = self.origin[tf]
        rotated = o + np.einsum("nij,nj->ni", self.rotation[tf], xf - o)
        out[f] = xf + share[:, None] * (rotated - xf)
        return out


def crease_probes(tri_uv: FloatArray) -> FloatArray:
    """Where a triangle with pixel corners ``tri_uv`` (T, 3, 2) is probed for a crease:
    its edge midpoints and its centroid, (T, 4, 2)."""
    return np.stack(
        [
            (tri_uv[:, 0] + tri_uv[:, 1]) / 2,
            (tri_uv[:, 1] + tri_uv[:, 2]) / 2,
            (tri_uv[:, 2] + tri_uv[:, 0]) / 2,
            tri_uv.mean(axis=1),
        ],
        axis=1,
    )


def unfold_creases(
    surface: Surface,
    tri_uv: FloatArray,
    tris: IntArray,
    points: FloatArray,
    probes: FloatArray | None = None,
) -> Unfolding:
    """Unfold the creased triangles among ``tris`` (T, 3) (vertex indices into ``points``
    (N, 3)), whose pixel corners are ``tri_uv`` (T, 3, 2). ``probes`` (T, 4, 3): the
    surface at their :func:`crease_probes`, when the caller has sampled it already."""
    tri_pts = points[tris]
    xs = surface.points_at(crease_probes(tri_uv)) if probes is None else probes  # (T, 4, 3)
    normals, area2 = planes_first(corners_first(tri_pts))
    return unfold_measured(
        tris,
        points,
        tri_pts,
        normals,
        area2,
        xs.transpose(2, 1, 0),
        ruled_triangles(surface, points, tris),
        snapped_walls(surface),
        pixel_spans(tri_uv, tri_pts),
    )


def sensed(surface: Surface) -> bool:
    """Whether ``surface`` was measured by a depth sensor (its meta's ``source`` is
    ``"depth"``): known to the sensor's millimetres, except on the planes it was
    snapped to (:func:`~adaproj_edge.geometry.planes.snap_planes`)."""
    return surface.meta.get("source") == "depth"


def snapped_walls(surface: Surface) -> FloatArray | None:
    """The planes (k, 4) a :func:`sensed` ``surface`` was snapped to, where there are
    two or more (the ``walls`` of :func:`unfold_measured`); else None."""
    if not sensed(surface):
        return None
    eq = plane_equations(surface.meta)
    return eq if eq.shape[0] >= 2 else None


def ruled_triangles(
    surface: Surface, points: FloatArray, tris: IntArray
) -> NDArray[np.bool_] | None:
    """Where (T,) a straight crease between curved sides may be looked for among the
    triangles ``tris`` (T, 3) of ``points`` (N, 3) on ``surface``
    (:mod:`~adaproj_edge.geometry.ruled_crease`; the ``may_rule`` of
    :func:`unfold_measured`): everywhere (None) on a surface known exactly, or on a
    :func:`sensed` one snapped to two planes or more; nowhere on another sensed one.

    The sides' patches must explain a side to :data:`RULED_FIT` of a triangle's size
    (tens of micrometres on the device's grid), and sensed depth is known to
    millimetres (the sensor's subpixel steps and noise) except on its snapped planes
    (to ~1e-7 of their depth): with fewer than two of them, no crease has both sides
    known so, and what a patch fits between the lattice's nodes is its own
    interpolant. On a bumpy wall's sessions (one plane) every mesh spent its whole
    budget of tries for nothing (0 or 1 of ~75 candidates found, a third of the mesh's
    time). Between two snapped walls everything is tried as before: the corner's
    crease triangles, in the lattice cells across the crease, have corners on neither
    plane, and how far those reach depends on how the planes were fitted."""
    if not sensed(surface) or snapped_walls(surface) is not None:
        return None
    return np.zeros(tris.shape[0], dtype=bool)


def unfold_measured(
    tris: IntArray,
    points: FloatArray,
    tri_pts: FloatArray,
    normals: FloatArray,
    area2: FloatArray,
    probes: FloatArray,
    may_rule: NDArray[np.bool_] | None = None,
    walls: FloatArray | None = None,
    pixel: FloatArray | None = None,
) -> Unfolding:
    """:func:`unfold_creases` of triangles whose corners ``tri_pts`` (T, 3, 3), unit
    normals (3, T) and twice the areas (T,) (:func:`~adaproj_edge.geometry.triangles.
    planes_first`) and surface at the probes (3, 4, T) (component-first) are known.
    ``may_rule`` (T,): where the sides' patches may be tried (a straight crease between
    curved sides, :mod:`~adaproj_edge.geometry.ruled_crease`; None: everywhere).
    ``walls`` (k, 4): the planes sensed depth was snapped to (:func:`snapped_walls`); a
    candidate across the line where two of them meet takes their planes
    (:mod:`~adaproj_edge.geometry.wall_crease`), without a search for its sides.
    ``pixel`` (T,): the most a pixel spans on each triangle
    (:func:`~adaproj_edge.geometry.ruled_crease.pixel_spans`): a probe that near a
    straight crease between curved sides is sampled across it (None: none is)."""
    size = np.sqrt(area2)
    # the probes' distances (4, T) to their triangle's plane
    signed = (
        (probes[0] - tri_pts[None, :, 0, 0]) * normals[0]
        + (probes[1] - tri_pts[None, :, 0, 1]) * normals[1]
        + (probes[2] - tri_pts[None, :, 0, 2]) * normals[2]
    )
    dist = np.abs(signed)
    off = np.max(np.where(np.isfinite(dist), dist, 0.0), axis=0)
    rough = off > ROUGH * size
    # a crease may run just past a corner: the triangle is then nearly flat, but its
    # chord plane is tilted by the sliver across the crease (up to ROUGH): it is a
    # candidate too, and it does not lend its tilted plane to its corners (a crease
    # half a pixel past a grid line leaves no triangle rough, only slivers; a surface
    # flat in every triangle costs no more than this look)
    slight = off > SLIGHT * size
    flat = ~slight
    seen_t = np.isfinite(normals).all(axis=0)
    planar = (off <= PLANAR * size) & seen_t
    # a flat triangle a little off its plane whose plane a vertex's flattest one refutes:
    # a sliver across a crease (a wall seen grazing, its triangles huge on the surface,
    # clipped half a pixel past a line): it lends no plane to that corner
    with np.errstate(invalid="ignore", divide="ignore"):  # (degenerate: not seen_t)
        rel_off = off / size
    refused = _refused_corners(
        tris, tri_pts, normals, size, probes, rel_off, flat & seen_t, planar, points.shape[0]
    )
    sliver = np.any(refused, axis=1)
    if not np.any(slight) and not np.any(sliver):
        return _nothing_folded(tri_pts, flat)
    # the plane of each vertex: area-weighted normal of its flat triangles, or where it
    # has none (a curved wall) of its smooth ones
    acc = _vertex_normals(tris, normals, size, flat & seen_t, points.shape[0], refused)
    loose = _vertex_normals(tris, normals, size, ~rough & slight & seen_t, points.shape[0])
    has_flat = np.any(acc != 0.0, axis=0)
    acc = np.where(has_flat, acc, loose)
    with np.errstate(invalid="ignore", divide="ignore"):
        vn = acc / np.sqrt(dot_first(acc, acc))  # (3, N)
    # a vertex all of whose triangles are rough (at the mesh's outline, where a crease
    # meets it) takes the plane of the neighbour it lies nearest to
    lost = np.asarray(~np.isfinite(vn).all(axis=0), dtype=bool)
    vn, lender = _borrowed_planes(tris[seen_t], points, vn)
    # ... unless it lies off that plane, on a wall whose strip at the frame's edge is
    # narrower than the row of cells the crease runs through: its own plane, then
    seen_b = np.asarray(seen_t, dtype=bool)
    own = _own_planes(tris, tri_pts, probes, size, seen_b, points, vn, lost, lender)
    vn[:, own[0]] = own[1]
    has_flat[own[0]] = True
    # only triangles whose corners' planes differ can hold a crease (checked for all
    # rough triangles at once; the loop below then handles the few that remain)
    rough_t = np.flatnonzero(slight | sliver)
    corner_n = vn[:, tris[rough_t]]  # (3, R, 3)
    with np.errstate(invalid="ignore"):
        differ = np.any(dot_first(corner_n, corner_n[:, :, :1]) < CREASE_COS, axis=1)
    cand = rough_t[differ & np.isfinite(corner_n).all(axis=(0, 2))]
    if cand.size == 0:
        return _nothing_folded(tri_pts, flat)
    lone, pair_a = _crease_groups(vn.T[tris[cand]])
    cand, lone, pair_a = cand[lone >= 0], lone[lone >= 0], pair_a[lone >= 0]
    # the two sides' planes, from the corners' planes; a: the side of corner 0
    pair = np.stack([(lone + 1) % 3, (lone + 2) % 3], axis=1)
    pair.sort(axis=1)
    corner_vn, corner_pt = vn.T[tris[cand]], tri_pts[cand]  # (C, 3, 3)
    at = np.arange(cand.size)
    n_pair, p_pair = corner_vn[at[:, None], pair], corner_pt[at[:, None], pair]  # (C, 2, 3)
    n_lone, p_lone = corner_vn[at, lone], corner_pt[at, lone]
    plane_pair = _pair_plane(n_pair, p_pair, n_lone)
    plane_lone = (n_lone / np.sqrt(dot_first(n_lone.T, n_lone.T))[:, None], p_lone)
    side = pair_a[:, None]
    na = np.where(side, plane_pair[0], plane_lone[0])
    pa = np.where(side, plane_pair[1], plane_lone[1])
    nb = np.where(side, plane_lone[0], plane_pair[0])
    pb = np.where(side, plane_lone[1], plane_pair[1])
    probe = probes[:, :, cand].transpose(2, 1, 0)  # (C, 4, 3)
    # a side none of whose corners has a planar triangle, across the crease from one
    # whose corners have (a wall seen grazing within one cell: its only triangles are
    # chords across the crease), takes the plane its own samples in the triangle lie
    # on, where they lie on one (noisy depth, planar nowhere, is not looked at)
    has_planar = _vertex_any(tris, planar, points.shape[0])
    on_a = (np.arange(3) == lone[:, None]) != pair_a[:, None]  # (C, 3) corners of side a
    planar_c = has_planar[tris[cand]]
    with_a = np.any(planar_c & on_a, axis=1)
    with_b = np.any(planar_c & ~on_a, axis=1)
    lacks_a, lacks_b = with_b & ~with_a, with_a & ~with_b
    if np.any(lacks_a | lacks_b):
        samples = np.concatenate([tri_pts[cand], probe], axis=1)  # (C, 7, 3)
        na, pa, nb, pb = _sample_planes(
            samples, (na, pa, nb, pb), lacks_a, lacks_b, PLANAR * size[cand]
        )
    # a crease only if the two planes explain the surface inside the triangle (a
    # strongly curved smooth patch, e.g. near a silhouette, is left as it is)
    seen = np.all(np.isfinite(probe), axis=2)
    fit = np.minimum(
        np.abs(np.einsum("cpj,cj->cp", probe - pa[:, None], na)),
        np.abs(np.einsum("cpj,cj->cp", probe - pb[:, None], nb)),
    )
    worst = np.max(np.where(seen, fit, -np.inf), axis=1)
    # straight creases: the two planes explain the surface; curved ones (a curved wall
    # meeting a floor): far better than the triangle does (a smooth curved patch is
    # explained about as badly by its corners' planes as by its chord)
    chord = np.max(np.where(np.isfinite(dist[:, cand]), dist[:, cand], 0.0), axis=0)
    # (a triangle with a sliver across the crease is nearly flat: its two planes must
    # explain it as well as a flat one's plane does - within SLIGHT: the corners' planes
    # come from flat triangles, each up to SLIGHT off its own - and it is never a
    # curved crease)
    rough_c = rough[cand]
    straight = worst <= np.where(rough_c, FIT * ROUGH, SLIGHT) * size[cand]
    # a straight crease with a curved side (a wall meeting a cone along a ruling): its
    # corners' planes miss the crease; each side's curve across it finds the planes
    curved_crease = rough_c & (worst <= CURVED_FIT * chord)
    # (a smooth curved patch's corners' planes differ by little more than a cell's bend:
    # only a crease of RULED_CREASE or more is looked at so; the shift it mends grows
    # with the crease's angle)
    sharp = np.einsum("cj,cj->c", na, nb) < RULED_CREASE_COS
    # a side with a corner without flat triangles is curved: its corners' planes are
    # tangent to it a cell away from the crease, so the sides' patches are tried first
    # (taken where one of them is bent); a rough triangle its corners' planes do not
    # explain is tried too (taken with plane patches as well)
    curved_side = ~np.all(has_flat[tris[cand]], axis=1)
    eligible = np.any(seen, axis=1) & sharp
    unexplained = rough_c & ~straight & ~curved_crease
    retry = np.flatnonzero(eligible & (curved_side | unexplained))
    if retry.size:
        # only next to a kink: a surface smooth at the grid's scale there (sensed depth,
        # smoothed across a jump: rough, its corners' planes far apart, yet no crease)
        # holds no crease for the patches to find, and trying costs ~0.4 ms each
        retry = retry[_kinked(tris, signed, size, points.shape[0])[tris[cand[retry]]].any(axis=1)]
    ruled = np.zeros(cand.size, dtype=bool)
    if retry.size and walls is not None:
        # between two snapped walls: their planes, not their patches' (found by the
        # same rule wherever the display's and the meshes' grids look)
        on_walls = wall_planes(
            retry, cand, tri_pts, probes, size, walls, (na, pa, nb, pb), pair_a, lone,
            RULED_CREASE_COS,
        )  # fmt: skip
        straight[on_walls] = True
        ruled[on_walls] = True
        curved_crease[on_walls] = False
        retry = retry[~np.isin(retry, on_walls)]
    if retry.size and may_rule is not None:
        retry = retry[may_rule[cand[retry]]]
    if retry.size:
        excluded = np.zeros(tris.shape[0], dtype=bool)
        excluded[rough_t[differ]] = True
        curved = ruled_planes(
            retry,
            cand,
            tris,
            tri_pts,
            normals,
            probes,
            size,
            (
                seen_t & ~slight,
                seen_t & ~rough & slight & ~excluded,
                seen_t & ~rough & slight & excluded,
            ),
            (na, pa, nb, pb),
            pair_a,
            lone,
            RULED_FIT,
            ~unexplained[retry],
            pixel,
        )
        straight[curved] = True
        ruled[curved] = True
        # (the ruled rule may regroup a corner: with the patch it lies on)
        pair = np.sort(np.stack([(lone + 1) % 3, (lone + 2) % 3], axis=1), axis=1)
        curved_crease[curved] = False
    keep = np.any(seen, axis=1) & (straight | curved_crease)
    if not np.any(keep):
        return _nothing_folded(tri_pts, flat)
    t_count = tris.shape[0]
    out = tri_pts.copy()
    nan3 = np.full((t_count, 3), np.nan)
    unfolding = Unfolding(
        out,
        np.zeros(t_count, dtype=bool),
        nan3,
        nan3.copy(),
        nan3.copy(),
        nan3.copy(),
        np.broadcast_to(np.eye(3), (t_count, 3, 3)).copy(),
        np.zeros((t_count, 3)),
        np.zeros(t_count),
        np.zeros(t_count, dtype=bool),
        flat,
    )
    # (all at once: one rotation per kept candidate)
    kept = np.flatnonzero(keep)
    t = cand[kept]
    rot, origin = _unfolding_rotations(pa[kept], na[kept], pb[kept], nb[kept])
    # the corners on side b: the lone corner when the pair is side a, else the pair
    on_b = (np.arange(3) == lone[kept, None]) == pair_a[kept, None]  # (K, 3)
    corners = tri_pts[t]  # (K, 3, 3)
    turned = origin[:, None] + np.einsum("kij,kcj->kci", rot, corners - origin[:, None])
    out[t] = np.where(on_b[:, :, None], turned, corners)
    unfolding.folded[t] = True
    unfolding.normal_a[t], unfolding.point_a[t] = na[kept], pa[kept]
    unfolding.normal_b[t], unfolding.point_b[t] = nb[kept], pb[kept]
    unfolding.rotation[t], unfolding.origin[t] = rot, origin
    unfolding.ruled[t] = ruled[kept]
    # a curved crease: the side choice softened
    unfolding.softness[t] = np.where(straight[kept], 0.0, SOFTNESS * worst[kept])
    return unfolding


def _kinked(tris: IntArray, signed: FloatArray, size: FloatArray, n: int) -> NDArray[np.bool_]:
    """Which of the ``n`` vertices (n,) have a triangle of ``tris`` (T, 3) with a kink:
    its probes' signed distances ``signed`` (4, T) to its plane (edge midpoints, then
    centroid) are not a quadratic's (on one, the centroid's is 4/9 of the midpoints'
    sum) to :data:`KINK` of its ``size``."""
    with np.errstate(invalid="ignore"):
        miss = np.abs(signed[3] - 4.0 / 9.0 * (signed[0] + signed[1] + signed[2]))
        kinked = (miss > KINK * size).astype(np.float64)
    out: NDArray[np.bool_] = np.bincount(tris.ravel(), np.repeat(kinked, 3), minlength=n) > 0
    return out


def _vertex_normals(
    tris: IntArray,
    normals: FloatArray,
    size: FloatArray,
    use: NDArray[np.bool_],
    n: int,
    refused: NDArray[np.bool_] | None = None,
) -> FloatArray:
    """Sum (3, n) at each of the ``n`` vertices of the normals (3, T) of the triangles
    ``tris`` (T, 3) where ``use`` holds, weighted by their squared ``size``; not at the
    corners ``refused`` (T, 3) marks."""
    at = np.flatnonzero(use)
    weighted = normals[:, at] * size[at] ** 2  # (3, S), added at each corner
    corners = tris[at].ravel()  # (3 S,): corner k of triangle t at 3 t + k
    keep = None if refused is None or not np.any(refused) else ~refused[at].ravel()
    acc = np.empty((3, n))
    for axis in range(3):
        w = np.repeat(weighted[axis], 3)
        if keep is None:
            acc[axis] = np.bincount(corners, w, minlength=n)
        else:
            acc[axis] = np.bincount(corners[keep], w[keep], minlength=n)
    return acc


def _vertex_any(tris: IntArray, use: NDArray[np.bool_], n: int) -> NDArray[np.bool_]:
    """(n,) whether each of the ``n`` vertices is a corner of a triangle of ``tris``
    (T, 3) where ``use`` (T,) holds."""
    out = np.zeros(n, dtype=bool)
    out[tris[use].ravel()] = True
    return out


def _refused_corners(
    tris: IntArray,
    tri_pts: FloatArray,
    normals: FloatArray,
    size: FloatArray,
    probes: FloatArray,
    rel_off: FloatArray,
    flat: NDArray[np.bool_],
    planar: NDArray[np.bool_],
    n: int,
) -> NDArray[np.bool_]:
    """(T, 3): the corners of the ``flat`` (T,) but not ``planar`` triangles ``tris``
    (T, 3) (corners ``tri_pts`` (T, 3, 3), unit normals (3, T), ``size`` (T,), surface
    at the probes (3, 4, T), the probes off their plane by ``rel_off`` (T,) of their
    size) whose plane differs by more than a crease's angle from that of the flattest
    flat triangle at the same vertex (of ``n``), where the triangle's other corners and
    its probes lie on one plane: there the triangle is a chord across a crease that
    clips a sliver off it at that corner, not a piece of the vertex's plane."""
    out = np.zeros(tris.shape, dtype=bool)
    near = flat & ~planar
    if not np.any(near) or not np.any(planar):
        return out
    # only at the vertices of such triangles that also have planar ones
    touched = _vertex_any(tris, near, n) & _vertex_any(tris, planar, n)
    at = np.flatnonzero(flat & touched[tris].any(axis=1))
    if at.size == 0:
        return out
    v = tris[at].ravel()
    t = np.repeat(at, 3)
    k = np.tile(np.arange(3), at.size)
    mine = touched[v]
    v, t, k = v[mine], t[mine], k[mine]
    order = np.lexsort((rel_off[t], v))  # by vertex, the flattest first
    first = np.unique(v[order], return_index=True)[1]
    flattest = np.full(n, -1, dtype=np.intp)
    flattest[v[order][first]] = t[order][first]
    ref = flattest[v]
    with np.errstate(invalid="ignore"):
        apart = dot_first(normals[:, t], normals[:, ref]) < CREASE_COS
    hit = np.flatnonzero(near[t] & apart)
    if hit.size == 0:
        return out
    # ... and where the triangle is a piece of one plane but for that corner: its other
    # corners and its probes lie on one within PLANAR (a sliver; on sensed depth a
    # large flat-looking triangle is noise, not a sliver)
    th, kh = t[hit], k[hit]
    samples = np.concatenate([tri_pts[th], probes[:, :, th].transpose(2, 1, 0)], axis=1)
    use = np.all(np.isfinite(samples), axis=2)
    use[np.arange(th.size), kh] = False
    good = _plane_fits(samples, use, PLANAR * size[th])[2]
    out[th[good], kh[good]] = True
    return out


def _plane_fits(
    x: FloatArray, use: NDArray[np.bool_], tol: FloatArray
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Least-squares planes of the points ``x`` (C, K, 3) where ``use`` (C, K): unit
    normals (C, 3), centres (C, 3), and whether four or more points (three always
    would) lie on the plane within ``tol`` (C,) and span it (their second principal
    spread above 100 ``tol``: not a line of points)."""
    count = use.sum(axis=1)
    w = use.astype(np.float64)
    xs = np.where(use[:, :, None], x, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = np.einsum("ck,ckj->cj", w, xs) / count[:, None]
    centre = np.where(count[:, None] > 0, centre, 0.0)
    d = (xs - centre[:, None]) * w[:, :, None]
    vals, vecs = np.linalg.eigh(np.einsum("cki,ckj->cij", d, d))
    normal = vecs[:, :, 0]
    off = np.abs(np.einsum("ckj,cj->ck", d, normal)) * w
    spread = np.sqrt(np.maximum(vals[:, 1], 0.0) / np.maximum(count, 1))
    good = (count >= 4) & (off.max(axis=1, initial=0.0) <= tol) & (spread > 100 * tol)
    return normal, centre, good


def _sample_planes(
    samples: FloatArray,
    planes: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    redo_a: NDArray[np.bool_],
    redo_b: NDArray[np.bool_],
    tol: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The planes (na, pa, nb, pb: (C, 3) each) of the crease candidates, with side a's
    (where ``redo_a`` (C,)) and side b's (``redo_b``) replaced by the plane
    (:func:`_plane_fits`, within ``tol`` (C,)) that the candidate's ``samples`` (C, K,
    3: its corners and probes) nearer that side's plane than the other's lie on."""
    na, pa, nb, pb = (x.copy() for x in planes)
    seen = np.all(np.isfinite(samples), axis=2)
    x = np.where(seen[:, :, None], samples, 0.0)
    with np.errstate(invalid="ignore"):
        da = np.abs(np.einsum("ckj,cj->ck", x - pa[:, None], na))
        db = np.abs(np.einsum("ckj,cj->ck", x - pb[:, None], nb))
    for redo, near_side, n_side, p_side in ((redo_a, da < db, na, pa), (redo_b, db < da, nb, pb)):
        c = np.flatnonzero(redo)
        if c.size == 0:
            continue
        normal, centre, good = _plane_fits(x[c], (seen & near_side)[c], tol[c])
        normal *= np.where(np.einsum("cj,cj->c", normal, n_side[c]) < 0, -1.0, 1.0)[:, None]
        good &= np.einsum("cj,cj->c", normal, n_side[c]) >= SAME_SIDE_COS
        n_side[c[good]] = normal[good]
        p_side[c[good]] = centre[good]
    return na, pa, nb, pb


def _borrowed_planes(
    tris: IntArray, points: FloatArray, vn: FloatArray
) -> tuple[FloatArray, IntArray]:
    """The vertex planes' normals ``vn`` (3, N), where a vertex of ``tris`` (T, 3) has
    none (NaN), the one of its neighbours (along the triangles' sides) whose plane it
    lies nearest to, if any has one; and that neighbour (N,), -1 where none lent."""
    lender = np.full(vn.shape[1], -1, dtype=np.intp)
    lost = np.any(~np.isfinite(vn), axis=0)
    if not np.any(lost[tris]):
        return vn, lender
    v = np.concatenate([tris[:, 0], tris[:, 1], tris[:, 2], tris[:, 1], tris[:, 2], tris[:, 0]])
    w = np.concatenate([tris[:, 1], tris[:, 2], tris[:, 0], tris[:, 0], tris[:, 1], tris[:, 2]])
    use = lost[v] & ~lost[w]
    v, w = v[use], w[use]
    if v.size == 0:
        return vn, lender
    off = np.abs(np.einsum("ij,ji->i", points[v] - points[w], vn[:, w]))
    order = np.lexsort((off, v))  # by vertex, the nearest plane first
    first = np.unique(v[order], return_index=True)[1]
    out = vn.copy()
    out[:, v[order][first]] = vn[:, w[order][first]]
    lender[v[order][first]] = w[order][first]
    return out, lender


def _own_planes(
    tris: IntArray,
    tri_pts: FloatArray,
    probes: FloatArray,
    size: FloatArray,
    seen_t: NDArray[np.bool_],
    points: FloatArray,
    vn: FloatArray,
    lost: NDArray[np.bool_],
    lender: IntArray,
) -> tuple[IntArray, FloatArray]:
    """The vertices (V,) that had no plane of their own (``lost`` (N,)) and lie off the
    one their ``lender`` (N,) lent them (:func:`_borrowed_planes`; normals ``vn`` (3,
    N)) by more than :data:`SLIGHT` of their triangles' size, with the plane (3, V
    unit normals) that their triangles' samples (corners ``tri_pts`` (T, 3, 3) and
    probes (3, 4, T) of ``tris`` (T, 3) seen (``seen_t``)) off the lent plane lie on,
    within :data:`PLANAR` (:func:`_plane_fits`; where they do not, or are a line of
    points, the vertex keeps the lent plane).

    A wall whose strip at the frame's edge is narrower than the row (or column) of
    cells the crease runs through, or a corner of the frame the crease clips, has no
    flat triangle: each of its vertices borrowed a neighbour's plane, the other wall's,
    so its triangles' corners agreed and the crease went unfolded (a crease oblique in
    the frame: a band of a cell's width along it, mean angle error 7e-3 on a 60 deg
    corner).
    """
    none = (np.zeros(0, dtype=np.intp), np.zeros((3, 0)))
    at = np.flatnonzero(lost & (lender >= 0))
    if at.size == 0:
        return none
    t_idx = np.flatnonzero(seen_t)
    inc_v, inc_t = tris[t_idx].ravel(), np.repeat(t_idx, 3)
    mine = np.zeros(points.shape[0], dtype=bool)
    mine[at] = True
    inc_v, inc_t = inc_v[mine[inc_v]], inc_t[mine[inc_v]]
    order = np.argsort(inc_v, kind="stable")
    inc_v, inc_t = inc_v[order], inc_t[order]
    verts, start, count = np.unique(inc_v, return_index=True, return_counts=True)
    rank = np.arange(inc_v.size) - np.repeat(start, count)
    row = np.repeat(np.arange(verts.size), count)
    reach = np.zeros(verts.size)
    np.maximum.at(reach, row, size[inc_t])
    src = lender[verts]
    n_lent, p_lent = vn[:, src].T, points[src]  # (V, 3)
    tol = SLIGHT * reach
    off_self = np.abs(np.einsum("vj,vj->v", points[verts] - p_lent, n_lent))
    by_tri = np.full((verts.size, int(count.max()), 7, 3), np.nan)
    by_tri[row, rank] = np.concatenate(
        [tri_pts[inc_t], probes[:, :, inc_t].transpose(2, 1, 0)], axis=1
    )
    samples = by_tri.reshape(verts.size, -1, 3)
    seen = np.all(np.isfinite(samples), axis=2)
    x = np.where(seen[:, :, None], samples, 0.0)
    off = np.abs(np.einsum("vkj,vj->vk", x - p_lent[:, None], n_lent))
    use = seen & (off > tol[:, None])
    normal, centre, good = _plane_fits(x, use, PLANAR * reach)
    # (a probe within a pixel of the crease is interpolated between the walls: one or
    # two samples the first fit misses are left out once, where six or more stay)
    res = np.abs(np.einsum("vkj,vj->vk", x - centre[:, None], normal))
    near = use & (res <= 10 * PLANAR * reach[:, None])
    left_out = use.sum(axis=1) - near.sum(axis=1)
    again = np.flatnonzero(~good & (left_out <= 2) & (near.sum(axis=1) >= 6))
    use_again = near[again]
    fit_again = _plane_fits(x[again], use_again, PLANAR * reach[again])
    normal[again], centre[again], good[again] = fit_again
    normal *= np.where(np.einsum("vj,vj->v", normal, centre) > 0, -1.0, 1.0)[:, None]
    good &= np.einsum("vj,vj->v", normal, n_lent) < CREASE_COS
    off_lent = off_self > tol
    # a vertex whose samples off the lent plane are a line of points (the strip's edge
    # of the frame alone) takes a fitted neighbour's plane when it lies on it
    has = good & off_lent
    plane_n = np.where(has[:, None], normal, np.nan)
    plane_p = np.where(has[:, None], points[verts], np.nan)
    slot = np.full(points.shape[0], -1, dtype=np.intp)
    slot[verts] = np.arange(verts.size)
    a = np.concatenate([tris[:, 0], tris[:, 1], tris[:, 2], tris[:, 1], tris[:, 2], tris[:, 0]])
    b = np.concatenate([tris[:, 1], tris[:, 2], tris[:, 0], tris[:, 0], tris[:, 1], tris[:, 2]])
    pairs = np.unique(np.stack([slot[a], slot[b]], axis=1), axis=0)
    pairs = pairs[(pairs >= 0).all(axis=1)]
    for _ in range(verts.size):
        wanting = ~has[pairs[:, 0]] & has[pairs[:, 1]] & off_lent[pairs[:, 0]]
        i, k = pairs[wanting, 0], pairs[wanting, 1]
        d = np.abs(np.einsum("ij,ij->i", points[verts[i]] - plane_p[k], plane_n[k]))
        on = d <= PLANAR * reach[i]
        i, k = i[on], k[on]
        if i.size == 0:
            break
        i, first = np.unique(i, return_index=True)
        plane_n[i], plane_p[i] = plane_n[k[first]], plane_p[k[first]]
        has[i] = True
    return verts[has], plane_n[has].T


def _nothing_folded(tri_pts: FloatArray, flat: NDArray[np.bool_]) -> Unfolding:
    """The :class:`Unfolding` of triangles ``tri_pts`` (T, 3, 3) without a crease (its
    corners are ``tri_pts`` themselves); ``flat`` (T,) as :class:`Unfolding` has it."""
    t_count = tri_pts.shape[0]
    nan3 = np.full((t_count, 3), np.nan)
    rotation = np.zeros((t_count, 3, 3))
    rotation[:, 0, 0] = rotation[:, 1, 1] = rotation[:, 2, 2] = 1.0
    return Unfolding(
        tri_pts,
        np.zeros(t_count, dtype=bool),
        nan3,
        nan3.copy(),
        nan3.copy(),
        nan3.copy(),
        rotation,
        np.zeros((t_count, 3)),
        np.zeros(t_count),
        np.zeros(t_count, dtype=bool),
        flat,
    )


def _crease_groups(normals: FloatArray) -> tuple[IntArray, NDArray[np.bool_]]:
    """The corners, by their planes' normals (C, 3, 3), on either side of a crease.

    The two most different planes are its sides and the third corner joins the nearer
    one, if it is much nearer to it (on a curved wall two corners' planes differ a
    little). Returns the corner alone on its side (C,), -1 without a single crease (no
    two planes far enough apart, or three different planes), and whether the pair is
    the side of corner 0 (C,).
    """
    normals = normals.transpose(2, 0, 1)  # component-first (xyz, C, corner)
    pairs = np.array([(0, 1), (0, 2), (1, 2)])
    dots = dot_first(normals[:, :, pairs[:, 0]], normals[:, :, pairs[:, 1]])  # (C, 3)
    first = np.argmin(dots, axis=1)  # the two most different corners i, j
    i, j = pairs[first, 0], pairs[first, 1]
    at = np.arange(dots.shape[0])
    lowest = dots[at, first]
    crease = np.arccos(np.clip(lowest, -1.0, 1.0))
    k = 3 - i - j
    to_i = dot_first(normals[:, at, k], normals[:, at, i])
    to_j = dot_first(normals[:, at, k], normals[:, at, j])
    partner_i = to_i >= to_j
    near = np.arccos(np.clip(np.maximum(to_i, to_j), -1.0, 1.0))
    lone = np.where(partner_i, j, i)  # k joins its partner, the other stays alone
    single = (lowest < CREASE_COS) & (near <= 0.5 * crease)
    return np.where(single, lone, -1), lone != 0


def _pair_plane(
    normals: FloatArray, points: FloatArray, other: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The plane (unit normals (C, 3), points (C, 3)) of the sides with two corners, with
    normals ``normals`` (C, 2, 3) at ``points`` (C, 2, 3): their mean normal through
    their mean point; but when their normals differ much (a corner on the crease itself
    has a mix of both sides' normals), the corner farthest from the other side (its
    normal ``other`` (C, 3))."""
    n = normals[:, 0] + normals[:, 1]
    with np.errstate(invalid="ignore", divide="ignore"):  # (only used where they agree)
        mean_n = n / np.sqrt(dot_first(n.T, n.T))[:, None]
    mean_p = (points[:, 0] + points[:, 1]) / 2
    apart = dot_first(normals[:, 0].T, normals[:, 1].T) < SAME_SIDE_COS
    far = np.argmin(dot_first(normals.T, other.T[:, None]), axis=0)
    at = np.arange(normals.shape[0])
    return (
        np.where(apart[:, None], normals[at, far], mean_n),
        np.where(apart[:, None], points[at, far], mean_p),
    )


def _unfolding_rotations(
    pa: FloatArray, na: FloatArray, pb: FloatArray, nb: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Rotations (K, 3, 3) about the lines where planes (pa, na) and (pb, nb) (K, 3 each)
    meet that turn plane b into plane a (its far side onto a's extension, since both
    normals face the viewer), and a point (K, 3) of each line."""
    d = np.cross(nb, na)
    sin = np.sqrt(np.einsum("kj,kj->k", d, d))
    d = d / sin[:, None]
    rhs = np.stack(
        [
            np.einsum("kj,kj->k", na, pa),
            np.einsum("kj,kj->k", nb, pb),
            np.einsum("kj,kj->k", d, pa),
        ],
        axis=1,
    )
    origin: FloatArray = np.linalg.solve(np.stack([na, nb, d], axis=1), rhs[:, :, None])[:, :, 0]
    angle = np.arctan2(sin, np.einsum("kj,kj->k", nb, na))
    zero = np.zeros_like(sin)
    k = np.stack(
        [
            np.stack([zero, -d[:, 2], d[:, 1]], axis=1),
            np.stack([d[:, 2], zero, -d[:, 0]], axis=1),
            np.stack([-d[:, 1], d[:, 0], zero], axis=1),
        ],
        axis=1,
    )
    rot: FloatArray = (
        np.eye(3)
        + np.sin(angle)[:, None, None] * k
        + (1 - np.cos(angle))[:, None, None] * np.matmul(k, k)
    )
    return rot, origin
