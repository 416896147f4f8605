"""The maximal inscribed axis-aligned rectangle of a given aspect inside a triangle mesh.

Paper §4.1: the content rectangle becomes the maximal inscribed rectangle (same aspect
ratio, upright) of the region the warped mesh covers, so no content is ever lost.

With the aspect ratio folded into the y axis the wanted rectangle is a square, and the
largest square centred at a point c inside the region has half-side
``r(c) = min over boundary edges of the L-infinity distance from c to the edge`` (the
region's boundary, holes included, is the set of mesh edges that belong to one
triangle only). The search starts from a coarse raster (the pixel with the largest
chessboard distance to the outside, from ``cv2.distanceTransform``) and then climbs
``r(c)`` exactly with a shrinking pattern search, so the result is exact, not limited by
the raster, and inside the region by construction. Each of its steps evaluates ``r`` over
the edges that can be the nearest to its trials (:class:`_Nearby`), the very values it
would get over all of them; the distance to an edge is the largest of three gaps
(:class:`Segments`). A warm start (the previous frame's centre) skips the raster.

Where the largest rectangle can slide (content narrower than the region, a region
wider at one end), where it ends up is a matter of taste, not of size: among the
rectangles at most :data:`NEAR` (10 %) narrower than the largest, the one whose centre
is nearest the region's area centroid is taken (:func:`_centre`), so the picture sits
in the middle of the lit surface. On a flat wall nothing is lost (the largest slides
freely); on a wall tilted 35 degrees the largest sits against the far edge and the
centred one is 9 % narrower.

Content turned upright in a rolled projector's frame meets a region whose sides are
not axis-aligned: ``r`` then has a sharp ridge running obliquely along the sides the
square touches, which the eight directions of the pattern cannot follow; the pattern
also steps along the region's two dominant side directions (:func:`side_directions`).
Along such a ridge ``r`` is nearly flat, often with a maximum at either end that wins
by 0.1 % one frame and loses the next; the centring above also keeps consecutive
frames from jumping between them.

That centring alone is not continuous in the region, though: the climb that finds the
largest lands in one local optimum or another from one estimate of a surface to the
next (a corner's unfolded region has several), the centring starts from where it
landed, and along a nearly flat ridge the point where the clearance falls to 90 % of
the largest moves far for a small change of that largest. A rectangle to ``keep``
(the last one shown, on the same surface) is therefore kept where it is while its
clearance stays within :data:`NEAR` + :data:`KEEP_SLACK` of the largest found from it
or from the raster, and moved to the nearest such centre when it does not; only an
optimum :data:`CLEARLY` larger elsewhere replaces it (:func:`_kept`).
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.triangles import unique_edges

RASTER = 256
TOLERANCE = 4e-4  # the search stops at steps this small (of the region's extent)
NEAR = 0.1  # a rectangle this much narrower than the largest may be taken to be centred
KEEP_SLACK = 0.05  # a kept centre may be narrower again by this much of the largest
CLEARLY = 0.1  # an optimum elsewhere this much larger than the kept one's replaces it
_SHIFT = 4
_DIRECTIONS = np.array(
    [[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=np.float64
)
_SCALES = np.array([1.0, 0.5, 0.25, 0.125])


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle ``[x0, x0 + width] x [y0, y0 + height]``."""

    x0: float
    y0: float
    width: float
    height: float


def boundary_edges(tris: IntArray) -> IntArray:
    """Edges (E, 2) that belong to exactly one of the triangles ``tris`` (T, 3)."""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    uniq, _, counts = unique_edges(e, int(tris.max()) + 1)
    out: IntArray = uniq[counts == 1]
    return out


def boundary_loops(edges: IntArray) -> list[IntArray] | None:
    """The boundary edges (E, 2) chained into closed loops of vertex indices; None when
    they do not chain simply (a vertex on more than two boundary edges)."""
    nxt: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        nxt.setdefault(a, []).append(b)
        nxt.setdefault(b, []).append(a)
    if any(len(x) != 2 for x in nxt.values()):
        return None
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, prev, cur = [start], -1, start
        seen.add(start)
        while True:
            a, b = nxt[cur]
            step = b if a == prev else a
            if step == start:
                break
            loop.append(step)
            seen.add(step)
            prev, cur = cur, step
        loops.append(np.array(loop, dtype=np.intp))
    return loops


class Segments:
    """Segments p0-p1 (E, 2) held as the per-edge constants the L-infinity distance needs
    (the searches evaluate it for thousands of point-segment pairs per placement).

    The square of half-side r centred at c meets a segment exactly when their
    projections overlap on the square's two axes and on the segment's normal (they are
    convex: a separating line, if any, is parallel to a side of one of them). So the
    distance - the least such r - is the largest of three gaps: from c to the segment's
    x range, to its y range, and along its normal ``n`` to its line, the last divided by
    ``|n_x| + |n_y|`` (the square's half-width along ``n`` per unit of r).
    """

    def __init__(self, p0: FloatArray, p1: FloatArray) -> None:
        x0, y0, x1, y1 = p0[:, 0], p0[:, 1], p1[:, 0], p1[:, 1]
        dx, dy = x1 - x0, y1 - y0
        self.mx, self.hx = 0.5 * (x0 + x1), 0.5 * np.abs(dx)  # x range: middle, half-width
        self.my, self.hy = 0.5 * (y0 + y1), 0.5 * np.abs(dy)
        s = np.abs(dx) + np.abs(dy)
        s[s == 0] = np.inf  # a point: no normal, the ranges alone
        self.normal = np.empty((2, len(s)))  # scaled by 1 / s
        np.divide(-dy, s, out=self.normal[0])
        np.divide(dx, s, out=self.normal[1])
        self.offset = self.normal[0] * x0 + self.normal[1] * y0

    def subset(self, keep: NDArray[np.bool_]) -> Segments:
        """The segments where ``keep`` (E,) holds."""
        out = Segments.__new__(Segments)
        out.mx, out.hx, out.my, out.hy = self.mx[keep], self.hx[keep], self.my[keep], self.hy[keep]
        out.normal, out.offset = self.normal[:, keep], self.offset[keep]
        return out

    def distances(self, c: FloatArray) -> FloatArray:
        """L-infinity distance (N, E) from each of the points ``c`` (..., 2) (N of them)
        to each segment."""
        c = c.reshape(-1, 2)
        out = np.abs(c[:, 0:1] - self.mx)
        out -= self.hx
        gap = np.abs(c[:, 1:2] - self.my)
        gap -= self.hy
        np.maximum(out, gap, out=out)
        gap = c @ self.normal
        gap -= self.offset
        np.abs(gap, out=gap)
        np.maximum(out, gap, out=out)
        return out

    def clearance(self, c: FloatArray) -> FloatArray:
        """L-infinity distance from points ``c`` (..., 2) to the nearest segment: (...)."""
        out: FloatArray = self.distances(c).min(axis=1).reshape(c.shape[:-1])
        return out


def _raster_start(
    v: FloatArray,
    tris: IntArray,
    resolution: int,
    bounds: tuple[FloatArray, FloatArray],
    boundary: IntArray | None = None,
    loops: list[IntArray] | None = None,
) -> tuple[FloatArray, float]:
    """Centre (2,) of the largest square in a raster of the region (``bounds``: its
    lowest and highest x, y), and the cell size (``loops``: :func:`boundary_loops` of
    ``boundary`` when known, [] when they do not chain simply)."""
    lo, hi = bounds
    extent = float(np.max(hi - lo))
    if not np.isfinite(extent) or extent <= 0:
        raise WarpError("the warped mesh has no area")
    cell = extent / (resolution - 3)
    origin = lo - 1.5 * cell
    shape = (int(np.ceil((hi[1] - lo[1]) / cell)) + 4, int(np.ceil((hi[0] - lo[0]) / cell)) + 4)
    mask = np.zeros(shape, dtype=np.uint8)
    q = np.rint((v - origin) / cell * (1 << _SHIFT)).astype(np.int32)
    if loops is None:
        loops = (None if boundary is None else boundary_loops(boundary)) or []
    if loops:  # the region's outline (holes included: filled even-odd)
        cv2.fillPoly(mask, [q[loop] for loop in loops], 1, lineType=cv2.LINE_8, shift=_SHIFT)
    else:
        cv2.fillPoly(mask, list(np.take(q, tris, axis=0)), 1, lineType=cv2.LINE_8, shift=_SHIFT)
    dist = cv2.distanceTransform(mask, cv2.DIST_C, 3)
    _, best, _, loc = cv2.minMaxLoc(dist)
    if best < 1:
        raise WarpError("the covered region is too small to place the content")
    return origin + cell * np.array(loc, dtype=np.float64), cell


def inscribed_rectangle(
    v: FloatArray,
    tris: IntArray,
    aspect: float,
    resolution: int = RASTER,
    boundary: IntArray | None = None,
    start: FloatArray | None = None,
    near: float = NEAR,
    loops: list[IntArray] | None = None,
    keep: FloatArray | None = None,
) -> Rect:
    """Largest rectangle of ``aspect`` (width / height) inside the union of triangles.

    Parameters
    ----------
    v : (n, 2) float array
        Vertex positions.
    tris : (T, 3) int array
        The triangles covering the region (holes are absent triangles).
    aspect : float
        Width over height of the wanted rectangle.
    resolution : int
        Raster of the starting point (the result does not depend on it except through
        which local optimum the search climbs).
    boundary : (E, 2) int array, optional
        :func:`boundary_edges` of ``tris``, when the caller has it already.
    start : (2,) float array, optional
        A centre to climb from instead of the raster's (warm start: the previous
        rectangle's centre while the mesh changes a little).
    near : float
        Of the rectangles at most this much narrower than the largest, the one centred
        nearest the region's area centroid is returned (0: the largest, wherever it is).
    loops : list of int arrays, optional
        :func:`boundary_loops` of ``boundary`` ([] when they do not chain simply), when
        the caller keeps them (they depend on the mesh's topology alone).
    keep : (2,) float array, optional
        The centre of the rectangle shown last (the same surface, estimated again): kept
        while it is nearly as large as the largest (see the module's description), so
        the placement is continuous in the region.
    """
    if tris.size == 0:
        raise WarpError("no surface triangles to place the content on")
    q = v * np.array([1.0, aspect])  # the wanted rectangle becomes a square
    edges = boundary_edges(tris) if boundary is None else boundary
    # (np.take, and reductions along rows of q.T: several times quicker than q[index]
    # and reductions down the columns of q at these sizes)
    p0, p1 = np.take(q, edges[:, 0], axis=0), np.take(q, edges[:, 1], axis=0)
    segs = Segments(p0, p1)
    qt = np.ascontiguousarray(q.T)
    bounds = qt.min(axis=1), qt.max(axis=1)
    extent = float(np.max(bounds[1] - bounds[0]))
    tol = TOLERANCE * extent
    region = _Triangles(qt, tris)
    sides = side_directions(p1 - p0)
    directions = np.concatenate([_DIRECTIONS, sides, -sides])
    pattern = _SCALES[:, None, None] * directions[None]  # (4, 12, 2)
    r = -1.0
    if start is not None:
        c = np.asarray(start, dtype=np.float64) * np.array([1.0, aspect])
        step = 0.002 * extent  # a warm start: the rectangle moves little
        r = float(segs.clearance(c))
        if not region.inside(c):
            r = -1.0
    if r <= 0:
        c, step = _raster_start(q, tris, resolution, bounds, edges, loops)
        r = float(segs.clearance(c))
    c, r = _climb(c, r, step, tol, segs, pattern)
    if keep is not None:
        ck = np.asarray(keep, dtype=np.float64) * np.array([1.0, aspect])
        kept = _kept(ck, c, r, near, extent, tol, segs, pattern, region)
        if kept is not None:
            c, r = kept
            return Rect(c[0] - r, (c[1] - r) / aspect, 2 * r, 2 * r / aspect)
    if near > 0:
        cc, rc = _centre(c, r, (1.0 - near) * r, region.centroid(), tol, segs, pattern)
        if region.inside(cc):  # (the clearance alone does not tell in from out)
            c, r = cc, rc
    return Rect(c[0] - r, (c[1] - r) / aspect, 2 * r, 2 * r / aspect)


def _kept(
    keep: FloatArray,
    c: FloatArray,
    r: float,
    near: float,
    extent: float,
    tol: float,
    segs: Segments,
    pattern: FloatArray,
    region: _Triangles,
) -> tuple[FloatArray, float] | None:
    """The square to show instead of a fresh search's (``c``, clearance ``r``, before
    centring) when the one shown last was centred at ``keep`` (2,) (in the square's
    units): ``keep`` itself while its clearance is at least ``1 - near - KEEP_SLACK``
    of the largest found (from the raster and from ``keep``), else the nearest centre
    that is; None (the fresh search's) when ``keep`` is outside the region or an
    optimum :data:`CLEARLY` larger than the one nearest ``keep`` is elsewhere."""
    if not region.inside(keep):
        return None
    rk = float(segs.clearance(keep))
    if rk <= 0:
        return None
    cw, rw = _climb(keep, rk, 0.002 * extent, tol, segs, pattern)
    if r > (1.0 + CLEARLY) * rw:
        return None
    least = (1.0 - near - KEEP_SLACK) * max(r, rw)
    if rk >= least:
        return keep, rk
    cc, rc = _centre(cw, rw, least, keep, tol, segs, pattern)
    return (cc, rc) if region.inside(cc) else None


def _climb(
    c: FloatArray,
    r: float,
    step: float,
    tol: float,
    segs: Segments,
    pattern: FloatArray,
) -> tuple[FloatArray, float]:
    """Pattern search from centre ``c`` (clearance ``r``), four step sizes per
    evaluation (step, step/2, step/4, step/8): move to the best trial that improves r
    and carry on at its step size (twice it after a move at the full step: the optimum
    may be far); when none improves, the step shrinks 16-fold. A trial farther (L-inf)
    than the clearance from the centre is not taken: within it no outline is crossed,
    so the search never leaves the region (outside it the clearance grows without
    bound, and so would the step).

    Each evaluation runs over the boundary edges that can be the nearest ones to its
    trials (:class:`_Nearby`): the same values, so the same path, as over all of them."""
    nearby = _Nearby(segs)
    trials = pattern.reshape(-1, 2)
    reach = np.abs(trials).max(axis=1)  # each trial's L-inf offset per step
    widest = float(reach.max())
    per_scale = pattern.shape[1]
    while step > tol:
        trial = trials * step
        trial += c
        rt = nearby.around(c, r, step).clearance(trial)
        if step * widest >= r:  # (else every trial is within the clearance)
            rt[step * reach >= r] = -np.inf
        k = int(rt.argmax())
        best = float(rt[k])
        if best > r:
            c, r = trial[k], best
            scale = k // per_scale
            step *= 2.0 if scale == 0 else _SCALES[scale]
        else:
            step *= _SCALES[-1] / 2
    return c, r


class _Nearby:
    """The segments that can be the nearest ones to points within ``reach`` (L-infinity)
    of an anchor of clearance r: those no farther than ``r + 2 reach`` from it (any
    point there is at most r + reach from its nearest, a farther segment more than
    that). The anchor moves to the search's centre when its trials would leave the
    reach; it holds them all when most of them are near anyway."""

    SHARE = 0.75  # a subset of more than this share of the segments: all of them
    REACH = 4.0  # the reach, in steps of the search at the anchor

    def __init__(self, segs: Segments) -> None:
        self.segs, self.near = segs, segs
        self.anchor = np.zeros(2)
        self.reach = -1.0

    def around(self, c: FloatArray, r: float, step: float) -> Segments:
        """The segments that can be nearest to points within ``step`` of ``c``
        (clearance ``r``)."""
        a = self.anchor  # (the L-inf distance by scalars: quicker than on 2-vectors)
        if max(abs(c[0] - a[0]), abs(c[1] - a[1])) + step > self.reach:
            reach = self.REACH * step
            keep = self.segs.distances(c[None, :])[0] <= r + 2.0 * reach
            if np.count_nonzero(keep) > self.SHARE * keep.size:
                self.near, self.reach = self.segs, np.inf
            else:
                self.near, self.reach, self.anchor = self.segs.subset(keep), reach, c
        return self.near


def side_directions(d: FloatArray, bins: int = 180) -> FloatArray:
    """The two dominant directions (2, 2) of segments ``d`` (E, 2): the length-weighted
    peaks of their angle histogram (modulo 180 degrees, the second at least 20 degrees
    from the first), each the weighted mean direction of its peak's segments."""
    dx, dy = d[:, 0], d[:, 1]
    length = np.sqrt(dx * dx + dy * dy)
    angle = np.mod(np.arctan2(dy, dx), np.pi)
    k = np.minimum((angle / np.pi * bins).astype(np.intp), bins - 1)
    hist = np.bincount(k, weights=length, minlength=bins)
    ring = np.concatenate([hist[-1:], hist, hist[:1]])
    smooth = hist + ring[:-2] + ring[2:]  # each bin with its two neighbours
    first = int(smooth.argmax())
    apart = bins // 9  # the second peak's least distance from the first, in bins
    smooth[np.arange(first - apart + 1, first + apart) % bins] = -1.0
    second = int(smooth.argmax())
    out = np.empty((2, 2))
    for i, b in enumerate((first, second)):
        # the peak's bins b - 1, b, b + 1 (modulo bins); doubled angles, so that
        # directions 180 degrees apart add up
        near = (k - (b - 1)) % bins <= 2
        z = complex(np.sum(length[near] * np.exp(2j * angle[near])))
        a = 0.5 * cmath.phase(z) if abs(z) > 0 else (b + 0.5) * math.pi / bins
        out[i] = math.cos(a), math.sin(a)
    return out


def _centre(
    c: FloatArray,
    r: float,
    least: float,
    goal: FloatArray,
    tol: float,
    segs: Segments,
    pattern: FloatArray,
) -> tuple[FloatArray, float]:
    """From centre ``c`` (clearance ``r``), the centre nearest ``goal`` (2,) whose
    clearance is still at least ``least``: a pattern search (straight toward the goal,
    and the climb's steps), moving while it gets nearer; returns it and its clearance.

    Only the trials nearer the goal than ``c`` can be moved to, so only theirs are
    measured (about half of the pattern's point away): the same move as measuring all."""
    gap = float(np.linalg.norm(goal - c))
    step = gap
    trials = pattern.reshape(-1, 2)
    n = _SCALES.size
    trial = np.empty((n + trials.shape[0], 2))  # toward the goal, then the pattern's
    while step > tol and gap > 0:
        np.multiply(np.minimum(_SCALES * step / gap, 1.0)[:, None], goal - c, out=trial[:n])
        np.multiply(trials, step, out=trial[n:])
        trial += c
        away = trial - goal
        away *= away
        gaps = np.sqrt(away[:, 0] + away[:, 1])
        nearer = np.flatnonzero(gaps < gap)  # (in the trials' order: ties go as before)
        if nearer.size:
            rt = segs.clearance(trial[nearer])
            fits = np.flatnonzero(rt >= least)
            if fits.size:
                k = int(fits[gaps[nearer[fits]].argmin()])
                c, r, gap = trial[nearer[k]].copy(), float(rt[k]), float(gaps[nearer[k]])
                continue
        step *= 0.5
    return c, r


class _Triangles:
    """The triangles ``tris`` (T, 3) over vertices ``vt`` (2, n) (x row, y row), their
    corners and sides gathered once for the tests of a placement (held corner by corner,
    (3, T): reductions over the three run along rows, quick)."""

    def __init__(self, vt: FloatArray, tris: IntArray) -> None:
        corners = np.ascontiguousarray(tris.T)
        self.x, self.y = np.take(vt[0], corners), np.take(vt[1], corners)  # (3, T)
        turn = [1, 2, 0]
        self.ex, self.ey = self.x[turn] - self.x, self.y[turn] - self.y  # sides

    def inside(self, c: FloatArray) -> bool:
        """Whether point ``c`` (2,) lies in one of the triangles."""
        s = self.ex * (c[1] - self.y)
        s -= self.ey * (c[0] - self.x)
        left, right = s >= 0, s <= 0
        return bool(np.any((left[0] & left[1] & left[2]) | (right[0] & right[1] & right[2])))

    def centroid(self) -> FloatArray:
        """Area centroid (2,) of the union of the triangles."""
        area = np.abs(self.ex[0] * self.ey[2] - self.ey[0] * self.ex[2])
        total = 3.0 * max(float(area.sum()), 1e-300)
        x, y = self.x, self.y
        return np.array([area @ (x[0] + x[1] + x[2]), area @ (y[0] + y[1] + y[2])]) / total
