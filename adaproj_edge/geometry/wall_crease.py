"""A crease between two snapped walls: its planes are the walls' own.

On sensed depth snapped to two planes or more (:func:`~adaproj_edge.geometry.planes.
snap_planes`), a crease triangle whose corners lie on two of the snapped planes is
where those two walls meet: the sides are those planes, known to ~1e-7 of their depth,
and the crease is the line they meet along. Fitting each side's patch from the
triangles around it (:mod:`~adaproj_edge.geometry.ruled_crease`) finds the same planes
where its points all lie on them, or bends a side through the lattice's interpolant in
the cell the crease runs through (a curve between the nodes, not the wall), and costs
~0.3 ms a try; the walls' equations cost nothing.

A side none of whose corners lies on a snapped plane (a triangle whose corners but
one fall in the lattice's cells across the crease) takes the other snapped plane whose
normal is nearest its corners' plane (often a mix of both walls' there). Either way the triangle
is taken only where the walls meet across it (within :data:`~adaproj_edge.geometry.
ruled_crease.REACH` of its size), at more than the ruled rule's angle, with a corner on
each side, and with every corner and probe near one of the two walls (within
:data:`NEAR` of its size: a triangle over an object in front of a wall is not).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.planes import on_planes
from adaproj_edge.geometry.ruled_crease import REACH

# a corner or probe of the triangle lies within this much of its size from one of the
# two walls: the lattice's interpolant in a cell of width w across a right-angled crease
# strays from both by up to w / 4 (1 % of a device grid triangle on the simulated OAK-D
# corner, 14 % where the lattice's cells are two thirds of the triangle's size); an
# object standing off the walls by more is no crease between them
NEAR = 0.25


def wall_planes(
    retry: IntArray,
    cand: IntArray,
    tri_pts: FloatArray,
    probes: FloatArray,
    size: FloatArray,
    walls: FloatArray,
    planes: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    pair_a: NDArray[np.bool_],
    lone: IntArray,
    min_cos: float,
) -> IntArray:
    """Of the crease candidates ``retry`` (indices into ``cand``, triangles with
    corners ``tri_pts`` (T, 3, 3), surface at their probes ``probes`` (3, 4, T) and
    ``size`` (T,)), those that lie across the line where two of the snapped ``walls``
    (k, 4: ``[n, d]``, ``n . X = d``) meet, at an angle whose cosine is below
    ``min_cos``. Their planes in ``planes`` (na, pa, nb, pb: (C, 3) each, normals
    facing the projector) are replaced, in place, by the walls' (each through the
    point of their line nearest the triangle's centre), and ``lone`` / ``pair_a`` (the
    corner groups, as in :mod:`~adaproj_edge.geometry.creases`) by the corners' walls:
    a corner on one wall goes with it, one on neither with the nearer."""
    na, pa, nb, pb = planes
    # the walls' normals facing the projector (at the origin: n . X = d < 0 in front)
    flip = np.where(walls[:, 3] > 0, -1.0, 1.0)
    wn, wd = walls[:, :3] * flip[:, None], walls[:, 3] * flip
    t = cand[retry]
    corners = tri_pts[t]  # (R, 3, 3)
    on = on_planes(corners.reshape(-1, 3), walls).reshape(t.size, 3, -1)  # (R, 3, k)
    found: list[int] = []
    for i, c in enumerate(retry.tolist()):
        on_b = (np.arange(3) == lone[c]) == pair_a[c]
        side_n = (na[c], nb[c])
        counts = (on[i, ~on_b].sum(axis=0), on[i, on_b].sum(axis=0))  # (k,) each
        chosen = [_wall_of(counts[s], wn, side_n[s]) for s in (0, 1)]
        if chosen[0] == chosen[1]:  # (the side with more corners on it keeps it)
            s = int(counts[0][chosen[0]] >= counts[1][chosen[0]]) if chosen[0] >= 0 else 0
            chosen[s] = -1
        for s in (0, 1):  # a side on no wall: the other wall its plane is nearer
            other = chosen[1 - s]
            if chosen[s] < 0 and other >= 0:
                chosen[s] = _other_wall(wn, other, side_n[s])
        a, b = chosen
        if a < 0 or b < 0 or a == b or float(wn[a] @ wn[b]) >= min_cos:
            continue
        o = corners[i].mean(axis=0)
        line = np.cross(wn[a], wn[b])
        line /= np.linalg.norm(line)
        at = np.linalg.solve(np.stack([wn[a], wn[b], line]), [wd[a], wd[b], line @ o])
        reach = float(size[t[i]])
        if float(np.linalg.norm(at - o)) > REACH * reach:
            continue
        samples = np.concatenate([corners[i], probes[:, :, t[i]].T])
        samples = samples[np.isfinite(samples).all(axis=1)]
        da, db = np.abs(samples @ wn[a] - wd[a]), np.abs(samples @ wn[b] - wd[b])
        if samples.shape[0] == 0 or np.minimum(da, db).max() > NEAR * reach:
            continue
        # each corner with the wall it lies on, else the nearer one
        in_b = np.where(on[i, :, a] & on[i, :, b], on_b, db[:3] < da[:3])
        in_b = np.where(on[i, :, a] != on[i, :, b], on[i, :, b], in_b)
        if in_b.all() or not in_b.any():
            continue
        if in_b[0]:  # (side a is the side of corner 0)
            a, b, in_b = b, a, ~in_b
        lone[c] = int(np.flatnonzero(in_b)[0]) if in_b.sum() == 1 else 0
        pair_a[c] = lone[c] != 0
        na[c], pa[c], nb[c], pb[c] = wn[a], at, wn[b], at.copy()
        found.append(c)
    return np.array(found, dtype=np.intp)


def _wall_of(count: IntArray, wn: FloatArray, n_side: FloatArray) -> int:
    """The wall (index into ``wn`` (k, 3)) most of a side's corners lie on (``count``
    (k,)), the one nearest the side's plane (normal ``n_side``) among equals; -1 if
    none does."""
    if not count.any():
        return -1
    score = count + 0.5 * (wn @ n_side)  # (the normals' cosine breaks ties only)
    return int(np.argmax(np.where(count > 0, score, -np.inf)))


def _other_wall(wn: FloatArray, other: int, n_side: FloatArray) -> int:
    """The wall (index into ``wn`` (k, 3), two or more) other than ``other`` whose
    normal is nearest the side's plane's ``n_side``."""
    cos = wn @ n_side
    cos[other] = -np.inf
    return int(np.argmax(cos))
