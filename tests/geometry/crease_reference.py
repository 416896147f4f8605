"""The crease unfolding triangle by triangle, as it was written before it was vectorised.

``adaproj_edge.geometry.creases`` decides every triangle at once; this module keeps the
plain per-triangle reading of the same rules (its loop over the rough triangles) so
that the tests can check the two agree. It returns, for each triangle, whether it is
unfolded and with which planes, rotation and softness. The product's caps on the ruled
crease's tries (``ruled_crease.MISSES``: a cost bound for surfaces rough all over;
``ruled_crease.BENT_MISSES``: for a curved crease's curved side) are not read here; on
the surfaces the two are compared on, the tries past them find nothing.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.creases import (
    CREASE_COS,
    CURVED_FIT,
    FIT,
    KINK,
    PLANAR,
    ROUGH,
    RULED_CREASE_COS,
    RULED_FIT,
    SAME_SIDE_COS,
    SLIGHT,
    SOFTNESS,
)
from adaproj_edge.geometry.ruled_crease import ACROSS_PIXELS, REACH, crease_planes, side_patch

# a side's surface points near a crease triangle: (side's corners (k,), its planes'
# normal, the other side's, wide: every smooth triangle within reach) -> (K, 3)
Cloud = Callable[[list[int], FloatArray, FloatArray, bool], FloatArray]


def crease_groups(normals: FloatArray) -> tuple[list[int], list[int]] | None:
    """Corners (by their planes' normals (3, 3)) on either side of a single crease, the
    side with corner 0 first; None without one."""
    pairs = ((0, 1), (0, 2), (1, 2))
    dots = [float(normals[i] @ normals[j]) for i, j in pairs]
    i, j = pairs[int(np.argmin(dots))]
    if min(dots) >= CREASE_COS:
        return None
    crease = float(np.arccos(np.clip(min(dots), -1.0, 1.0)))
    k = 3 - i - j
    to_i, to_j = float(normals[k] @ normals[i]), float(normals[k] @ normals[j])
    partner = i if to_i >= to_j else j
    if np.arccos(np.clip(max(to_i, to_j), -1.0, 1.0)) > 0.5 * crease:
        return None
    side = [partner, k]
    other = [j] if partner == i else [i]
    return (sorted(side), other) if 0 in side else (other, sorted(side))


def side_plane(
    normals: FloatArray, points: FloatArray, other: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """One side's plane: the mean of its corners' planes, or the corner farthest from
    the other side when its two corners' planes differ much."""
    if normals.shape[0] > 1 and float(normals[0] @ normals[1]) < SAME_SIDE_COS:
        k = int(np.argmin(normals @ other))
        return normals[k], points[k]
    n = normals.sum(axis=0)
    return n / np.linalg.norm(n), points.mean(axis=0)


def decide(
    t: int,
    corner_normals: FloatArray,
    corner_points: FloatArray,
    probes: FloatArray,
    chord_dist: FloatArray,
    size: float,
    cloud: Cloud | None = None,
    curved_side: bool = False,
    near_kink: bool = True,
    planar_corners: list[bool] | None = None,
    pixel: float | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, list[int]] | None:
    """Triangle ``t``'s crease, from its corners' planes' normals (3, 3), its corners (3, 3),
    its probes' surface points (4, 3) and their distances to its chord plane (4,): the
    planes a (na, pa) and b (nb, pb), the softness and the corners of side b; None when
    it is not unfolded. ``cloud`` gives a side's surface points near the triangle (for
    a straight crease with a curved side); ``curved_side``: a corner of the triangle
    has no flat triangles (its side is curved: the sides' patches are tried first);
    ``near_kink``: a triangle at its corners has a kink (the patches are tried only
    there); ``pixel``: the most a pixel spans on the triangle (metres; a probe within
    ``ACROSS_PIXELS`` of them from a straight crease between curved sides was sampled
    across it)."""
    groups = crease_groups(corner_normals)
    if groups is None:
        return None
    group_a, group_b = groups
    n_a, n_b = corner_normals[group_a], corner_normals[group_b]
    na, pa = side_plane(n_a, corner_points[group_a], n_b.mean(axis=0))
    nb, pb = side_plane(n_b, corner_points[group_b], n_a.mean(axis=0))
    if planar_corners is not None:
        # a side none of whose corners has a planar triangle, across from one whose
        # corners have: the plane of its own samples
        samples = np.concatenate([corner_points, probes])
        old = (na, pa, nb, pb)
        with_a = any(planar_corners[k] for k in group_a)
        with_b = any(planar_corners[k] for k in group_b)
        if with_b and not with_a:
            na, pa = sample_plane(samples, old[:2], old[2:], PLANAR * size)
        if with_a and not with_b:
            nb, pb = sample_plane(samples, old[2:], old[:2], PLANAR * size)
    probe = probes[np.all(np.isfinite(probes), axis=1)]
    if probe.size == 0:
        return None
    fit = np.minimum(np.abs((probe - pa) @ na), np.abs((probe - pb) @ nb))
    worst = float(np.max(fit))
    chord = float(np.max(np.where(np.isfinite(chord_dist), chord_dist, 0.0)))
    rough = chord > ROUGH * size  # else only a sliver: it must be straight
    straight = (FIT * ROUGH if rough else SLIGHT) * size
    explained = worst <= straight or (rough and worst <= CURVED_FIT * chord)
    unexplained = rough and not explained
    sharp = float(na @ nb) < RULED_CREASE_COS
    if cloud is not None and near_kink and sharp and (curved_side or unexplained):
        # a straight crease with a curved side: the sides' patches meet along it (where
        # the corners' planes explain the triangle, a side's patch must be bent)
        found = _ruled(probe, corner_points, size, cloud, groups, (na, nb), not unexplained, pixel)
        if found is not None:
            return found
    if not explained:
        return None
    softness = SOFTNESS * worst if worst > straight else 0.0
    return na, pa, nb, pb, softness, group_b


def plane_fit(points: FloatArray, tol: float) -> tuple[FloatArray, FloatArray] | None:
    """The least-squares plane (unit normal, centre) of the finite ``points`` (K, 3), if
    there are four or more, all within ``tol`` of it and spread across it (their second
    principal spread over 100 ``tol``); else None."""
    pts = points[np.all(np.isfinite(points), axis=1)]
    if len(pts) < 4:
        return None
    centre = pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(pts - centre)
    if np.max(np.abs((pts - centre) @ vt[2])) > tol or sv[1] / np.sqrt(len(pts)) <= 100 * tol:
        return None
    return vt[2], centre


def sample_plane(
    samples: FloatArray,
    side: tuple[FloatArray, FloatArray],
    other: tuple[FloatArray, FloatArray],
    tol: float,
) -> tuple[FloatArray, FloatArray]:
    """The plane (normal, point) of the triangle's ``samples`` (7, 3: corners, probes)
    nearer the plane ``side`` than the plane ``other`` (:func:`plane_fit`), if it is
    within 12 deg of ``side``'s; else ``side``."""
    n_side, p_side = side
    n_other, p_other = other
    mine = [
        x
        for x in samples
        if np.all(np.isfinite(x)) and abs((x - p_side) @ n_side) < abs((x - p_other) @ n_other)
    ]
    fit = plane_fit(np.array(mine).reshape(-1, 3), tol)
    if fit is None:
        return side
    normal = fit[0] if fit[0] @ n_side >= 0 else -fit[0]
    if normal @ n_side < SAME_SIDE_COS:
        return side
    return normal, fit[1]


def _ruled(
    probe: FloatArray,
    corner_points: FloatArray,
    size: float,
    cloud: Cloud,
    groups: tuple[list[int], list[int]],
    normals: tuple[FloatArray, FloatArray],
    bent: bool,
    pixel: float | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, list[int]] | None:
    """The ruled crease of :func:`decide`: its planes from the sides' patches, None
    where they do not explain the triangle (or, with ``bent``, are both planes)."""
    group_a, group_b = groups
    na, nb = normals
    d = np.cross(na, nb)
    d /= np.linalg.norm(d)
    origin = corner_points.mean(axis=0)
    tol = RULED_FIT * size
    # the sides' points from their corners' triangles, then (where those do not explain
    # the triangle) from every smooth triangle within reach
    for wide in (False, True):
        patch_a = side_patch(cloud(group_a, na, nb, wide), origin, na, tol)
        patch_b = side_patch(cloud(group_b, nb, na, wide), origin, nb, tol)
        if patch_a is None or patch_b is None:
            continue
        if bent and not (np.any(patch_a.coef[3:] != 0) or np.any(patch_b.coef[3:] != 0)):
            return None
        met = crease_planes(patch_a, patch_b, origin, d, size, tol)
        if met is None:
            continue
        off = np.minimum(np.abs(patch_a.height(probe)[0]), np.abs(patch_b.height(probe)[0]))
        if pixel is not None:
            # a probe within ACROSS_PIXELS pixels of the crease (the line both tangent
            # planes hold) is the point map interpolated across it: not held to a patch
            line = np.cross(met[0], met[2])
            line /= np.linalg.norm(line)
            rel = probe - met[1]
            beside = np.linalg.norm(np.cross(rel, line), axis=1) <= ACROSS_PIXELS * pixel
            off = np.where(beside, 0.0, off)
        if float(off.max()) > tol:
            continue
        # each corner goes with the patch it lies on (as its plane groups it where it
        # lies on both); the crease must run between them
        side_b = []
        for k in range(3):
            p = corner_points[k : k + 1]
            h_a, h_b = abs(patch_a.height(p)[0][0]), abs(patch_b.height(p)[0][0])
            if (k in group_b) if (h_a <= tol and h_b <= tol) else h_b < h_a:
                side_b.append(k)
        if len(side_b) in (0, 3):
            continue
        if 0 in side_b:  # side a is the side of corner 0
            side_b = [k for k in range(3) if k not in side_b]
            return met[2], met[3], met[0], met[1], 0.0, side_b
        return met[0], met[1], met[2], met[3], 0.0, side_b
    return None


def unfold_reference(
    tris: np.ndarray, points: FloatArray, probes: FloatArray, tri_uv: FloatArray | None = None
) -> dict[int, tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, list[int]]]:
    """Every triangle's crease decision, triangle by triangle: ``tris`` (T, 3) vertex
    indices into ``points`` (N, 3), ``probes`` (T, 4, 3) the surface at each triangle's
    edge midpoints and centroid, ``tri_uv`` (T, 3, 2) its pixel corners (None: no probe
    is taken for one sampled across a crease). Keys: the unfolded triangles."""

    def pixel_of(t: int) -> float | None:
        """The most a pixel spans along an edge of triangle ``t`` (metres)."""
        if tri_uv is None:
            return None
        spans = [
            float(np.linalg.norm(points[tris[t][k]] - points[tris[t][k - 1]]))
            / float(np.linalg.norm(tri_uv[t][k] - tri_uv[t][k - 1]))
            for k in range(3)
        ]
        return max((s for s in spans if np.isfinite(s)), default=0.0)

    normals: dict[int, FloatArray] = {}
    sizes: dict[int, float] = {}
    dists: dict[int, FloatArray] = {}
    offs: dict[int, float] = {}
    rough: set[int] = set()
    slight: set[int] = set()
    planar: set[int] = set()
    kinked_vertices: set[int] = set()
    for t, (a, b, c) in enumerate(tris):
        p0, p1, p2 = points[a], points[b], points[c]
        n = -np.cross(p1 - p0, p2 - p0)  # facing the projector
        area2 = float(np.linalg.norm(n))
        sizes[t] = float(np.sqrt(area2))
        normals[t] = n / area2 if area2 > 0 else np.full(3, np.nan)
        signed = (probes[t] - p0) @ normals[t]
        dists[t] = np.abs(signed)
        # a kink: the centroid's height is not 4/9 of the edge midpoints' (a quadratic's)
        miss = abs(float(signed[3] - 4.0 / 9.0 * (signed[0] + signed[1] + signed[2])))
        if miss > KINK * sizes[t]:
            kinked_vertices.update(int(v) for v in (a, b, c))
        finite = dists[t][np.isfinite(dists[t])]
        worst = float(finite.max()) if finite.size else 0.0
        offs[t] = worst / sizes[t] if sizes[t] > 0 else np.nan
        if worst > ROUGH * sizes[t]:
            rough.add(t)
        if worst > SLIGHT * sizes[t]:
            slight.add(t)
        if worst <= PLANAR * sizes[t] and np.all(np.isfinite(normals[t])):
            planar.add(t)
    # a flat triangle not planar whose plane differs from the flattest flat triangle's at
    # a vertex with planar triangles, and which is a piece of one plane but for that
    # corner, lends that vertex no plane (a sliver across a crease)
    flat_at: dict[int, list[int]] = {}
    for t, corners in enumerate(tris):
        if t not in slight and np.all(np.isfinite(normals[t])):
            for v in corners:
                flat_at.setdefault(int(v), []).append(t)
    refused: set[tuple[int, int]] = set()
    for v, ts in flat_at.items():
        if not any(t in planar for t in ts) or all(t in planar for t in ts):
            continue
        flattest = min(ts, key=lambda t: (offs[t], t))
        for t in ts:
            if t in planar or float(normals[t] @ normals[flattest]) >= CREASE_COS:
                continue
            # ... where the rest of the triangle (its other corners, its probes) is a
            # piece of one plane
            rest = [points[w] for w in tris[t] if w != v] + list(probes[t])
            if plane_fit(np.array(rest), PLANAR * sizes[t]) is not None:
                refused.add((t, v))
    slivers = {t for t, _ in refused}
    # a vertex's plane: from its flat triangles, or where it has none from its smooth ones
    flat_sum = np.zeros_like(points, dtype=np.float64)
    smooth_sum = np.zeros_like(points, dtype=np.float64)
    has_planar = np.zeros(points.shape[0], dtype=bool)
    for t, corners in enumerate(tris):
        if t in planar:
            has_planar[corners] = True
        if t in rough or not np.all(np.isfinite(normals[t])):
            continue
        for v in corners:
            if (t, int(v)) in refused:
                continue
            (smooth_sum if t in slight else flat_sum)[v] += normals[t] * sizes[t] ** 2
    has_flat = np.any(flat_sum != 0.0, axis=1, keepdims=True)
    vertex_sum = np.where(has_flat, flat_sum, smooth_sum)
    with np.errstate(invalid="ignore", divide="ignore"):
        vertex_n = vertex_sum / np.linalg.norm(vertex_sum, axis=1, keepdims=True)
    # a vertex without a plane (all its triangles rough) takes the plane of the
    # neighbour it lies nearest to
    borrowed = vertex_n.copy()
    for v in range(points.shape[0]):
        if np.all(np.isfinite(vertex_n[v])):
            continue
        best = np.inf
        for t, corners in enumerate(tris):
            if v not in corners or not np.all(np.isfinite(normals[t])):
                continue
            for w in corners:
                if w != v and np.all(np.isfinite(vertex_n[w])):
                    off = abs(float((points[v] - points[w]) @ vertex_n[w]))
                    if off < best:
                        best, borrowed[v] = off, vertex_n[w]
    vertex_n = borrowed
    out = {}
    if not slight and not slivers:
        return out
    # the triangles whose corners' planes differ: never a side's smooth neighbours
    differ = set()
    for t in slight | slivers:
        cn = vertex_n[tris[t]]
        if any(float(cn[i] @ cn[0]) < CREASE_COS for i in (1, 2)):
            differ.add(t)
    # a side's points: each vertex's flat triangles where it has any, else its smooth
    # ones that are no crease candidates, else its other smooth ones
    flat_of: dict[int, list[int]] = {}
    smooth_of: dict[int, list[int]] = {}
    other_of: dict[int, list[int]] = {}
    flat_t: list[int] = []  # (the flat triangles, the smooth ones no candidates)
    smooth_t: list[int] = []
    for t, corners in enumerate(tris):
        if t in rough or not np.all(np.isfinite(normals[t])):
            continue
        kind = flat_of if t not in slight else smooth_of if t not in differ else other_of
        (flat_t if t not in slight else smooth_t if t not in differ else []).append(t)
        for v in corners:
            kind.setdefault(int(v), []).append(t)

    def cloud_of(t: int) -> Cloud:
        def cloud(ks: list[int], n_side: FloatArray, n_other: FloatArray, wide: bool) -> FloatArray:
            near: set[int] = set()
            for k in ks:
                v = int(tris[t][k])
                near.update(flat_of.get(v) or smooth_of.get(v) or other_of.get(v) or [])
            if wide:  # every flat one and smooth one no candidate within reach
                centre = points[tris[t]].mean(axis=0)
                near = set()
                for u in flat_t + smooth_t:
                    gap = points[tris[u]].mean(axis=0) - centre
                    if float(gap @ gap) <= (REACH * sizes[t]) ** 2:
                        near.add(u)
            pts = [points[tris[t][k]] for k in ks]
            for u in sorted(near):
                if abs(float(normals[u] @ n_side)) > abs(float(normals[u] @ n_other)):
                    pts += [points[v] for v in tris[u]] + list(probes[u])
            out = np.array(pts, dtype=np.float64)
            return out[np.all(np.isfinite(out), axis=1)]

        return cloud

    for t in sorted(slight | slivers):
        corner_n = vertex_n[tris[t]]
        if not np.all(np.isfinite(corner_n)):
            continue
        curved_side = not all(bool(has_flat[v, 0]) for v in tris[t])
        near_kink = any(int(v) in kinked_vertices for v in tris[t])
        found = decide(
            t,
            corner_n,
            points[tris[t]],
            probes[t],
            dists[t],
            sizes[t],
            cloud_of(t),
            curved_side,
            near_kink,
            [bool(has_planar[v]) for v in tris[t]],
            pixel_of(t),
        )
        if found is not None:
            out[t] = found
    return out
