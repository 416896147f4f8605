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
the raster, and inside the region by construction.

Content turned upright in a rolled projector's frame meets a region whose sides are
not axis-aligned: ``r`` then has a sharp ridge running obliquely along the sides the
square touches (falling at a slope of about 1 across it, by a fraction of a per cent
along it), which the eight directions of the pattern cannot follow; the pattern also
steps along the region's two dominant side directions (:func:`side_directions`). Along
such a ridge ``r`` is nearly flat, often with a maximum at either end that wins by
0.1 % one frame and loses the next: consecutive frames would place the content
centimetres apart. With ``near`` > 0 (:func:`~adaproj_edge.warp.placement.place` asks
for it when the content is turned) the centre taken is the one nearest the region's
area centroid, on the way from there to the best centre found, whose square is within
``near`` of the largest: centred, at most ``near`` smaller.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.triangles import unique_edges

RASTER = 256
_SHIFT = 4
_DIRECTIONS = np.array(
    [[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=np.float64
)
_SCALES = np.array([1.0, 0.5, 0.25, 0.125])
_PATTERN = _SCALES[:, None, None] * _DIRECTIONS[None]  # (4, 8, 2)
NEAR = 0.03


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


def linf_clearance(c: FloatArray, p0: FloatArray, p1: FloatArray) -> FloatArray:
    """L-infinity distance from points ``c`` (..., 2) to the segments p0-p1 (E, 2),
    minimised over the segments: (...)."""
    a = p0[None, :, :] - c.reshape(-1, 1, 2)  # (N, E, 2): segment start relative to c
    d = (p1 - p0)[None, :, :]
    # f(t) = max(|a_x + t d_x|, |a_y + t d_y|) is convex and piecewise linear in t: its
    # minimum over [0, 1] is at an end or where |a_x + t d_x| = |a_y + t d_y|.
    ax, ay, dx, dy = a[..., 0], a[..., 1], d[..., 0], d[..., 1]
    best = np.minimum(
        np.maximum(np.abs(ax), np.abs(ay)), np.maximum(np.abs(ax + dx), np.abs(ay + dy))
    )
    for num, den in ((ay - ax, dx - dy), (-(ax + ay), dx + dy)):
        ok = np.abs(den) > 1e-300
        t = np.clip(num / np.where(ok, den, 1.0), 0.0, 1.0)
        f = np.maximum(np.abs(ax + t * dx), np.abs(ay + t * dy))
        best = np.minimum(best, np.where(ok, f, np.inf))
    out: FloatArray = best.min(axis=1).reshape(c.shape[:-1])
    return out


def _raster_start(v: FloatArray, tris: IntArray, resolution: int) -> tuple[FloatArray, float]:
    """Centre (2,) of the largest square in a raster of the region, and the cell size."""
    lo = v.min(axis=0)
    hi = v.max(axis=0)
    extent = float(np.max(hi - lo))
    if not np.isfinite(extent) or extent <= 0:
        raise WarpError("the warped mesh has no area")
    cell = extent / (resolution - 3)
    origin = lo - 1.5 * cell
    shape = (int(np.ceil((hi[1] - lo[1]) / cell)) + 4, int(np.ceil((hi[0] - lo[0]) / cell)) + 4)
    mask = np.zeros(shape, dtype=np.uint8)
    q = np.rint((v[tris] - origin) / cell * (1 << _SHIFT)).astype(np.int32)
    cv2.fillPoly(mask, list(q), 1, lineType=cv2.LINE_8, shift=_SHIFT)
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
    near: float = 0.0,
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
        When positive, the centre nearest the region's centroid whose rectangle is
        within this fraction of the largest (0: the largest the search finds).
    """
    if tris.size == 0:
        raise WarpError("no surface triangles to place the content on")
    q = v * np.array([1.0, aspect])  # the wanted rectangle becomes a square
    edges = boundary_edges(tris) if boundary is None else boundary
    p0, p1 = q[edges[:, 0]], q[edges[:, 1]]
    extent = float(np.max(np.ptp(q, axis=0)))
    tol = 1e-4 * extent
    sides = side_directions(p1 - p0)
    directions = np.concatenate([_DIRECTIONS, sides, -sides])
    pattern = _SCALES[:, None, None] * directions[None]
    r = -1.0
    if start is not None:
        c = np.asarray(start, dtype=np.float64) * np.array([1.0, aspect])
        step = 0.01 * extent
        r = float(linf_clearance(c, p0, p1))
        if not _inside(c, q, tris):
            r = -1.0
    if r <= 0:
        c, step = _raster_start(q, tris, resolution)
        r = float(linf_clearance(c, p0, p1))
    # pattern search, four step sizes per evaluation (step, step/2, step/4, step/8):
    # move to the best trial that improves the objective and carry on at its step size;
    # when none does, the step shrinks 16-fold
    while step > tol:
        trial = (c + step * pattern).reshape(-1, 2)
        rt = linf_clearance(trial, p0, p1)
        k = int(np.argmax(rt))
        if rt[k] > r:
            c, r = trial[k], float(rt[k])
            step *= _SCALES[k // len(directions)]
        else:
            step *= _SCALES[-1] / 2
    if near > 0:
        c, r = _nearest_to(_centroid(q, tris), c, r, near, q, tris, p0, p1)
    return Rect(c[0] - r, (c[1] - r) / aspect, 2 * r, 2 * r / aspect)


def side_directions(d: FloatArray, bins: int = 180) -> FloatArray:
    """The two dominant directions (2, 2) of segments ``d`` (E, 2): the length-weighted
    peaks of their angle histogram (modulo 180 degrees, the second at least 20 degrees
    from the first), each the weighted mean direction of its peak's segments."""
    length = np.linalg.norm(d, axis=1)
    angle = np.mod(np.arctan2(d[:, 1], d[:, 0]), np.pi)
    k = np.minimum((angle / np.pi * bins).astype(int), bins - 1)
    hist = np.bincount(k, weights=length, minlength=bins)
    smooth = hist + np.roll(hist, 1) + np.roll(hist, -1)
    first = int(np.argmax(smooth))
    gap = np.abs((np.arange(bins) - first + bins // 2) % bins - bins // 2)
    second = int(np.argmax(np.where(gap >= bins // 9, smooth, -1.0)))
    out = []
    for b in (first, second):
        near = np.abs((k - b + bins // 2) % bins - bins // 2) <= 1
        # double the angles so that directions 180 degrees apart add up
        z = np.sum(length[near] * np.exp(2j * angle[near]))
        a = 0.5 * np.angle(z) if abs(z) > 0 else (b + 0.5) * np.pi / bins
        out.append([np.cos(a), np.sin(a)])
    return np.array(out)


def _nearest_to(
    g: FloatArray,
    c: FloatArray,
    r: float,
    near: float,
    q: FloatArray,
    tris: IntArray,
    p0: FloatArray,
    p1: FloatArray,
) -> tuple[FloatArray, float]:
    """The centre nearest ``g`` on the segment from ``g`` to ``c`` (the best centre,
    clearance ``r``) inside the region whose clearance is within ``near`` of ``r``."""
    t = np.linspace(0.0, 1.0, 65)[:, None]
    pts = g + t * (c - g)
    rs = linf_clearance(pts, p0, p1)
    for k in np.flatnonzero(rs >= (1.0 - near) * r):
        if _inside(pts[k], q, tris):
            return pts[k], float(rs[k])
    return c, r


def _centroid(v: FloatArray, tris: IntArray) -> FloatArray:
    """The area centroid (2,) of the triangles ``tris`` over vertices ``v`` (n, 2)."""
    a, b, d = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    e1, e2 = b - a, d - a
    area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    total = float(area.sum())
    if total <= 0:
        out: FloatArray = v.mean(axis=0)
        return out
    out = (area[:, None] * (a + b + d) / 3.0).sum(axis=0) / total
    return out


def _inside(c: FloatArray, v: FloatArray, tris: IntArray) -> bool:
    """Whether point ``c`` lies in one of the triangles."""
    a, b, d = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]

    def side(p: FloatArray, q: FloatArray) -> FloatArray:
        out: FloatArray = (q[:, 0] - p[:, 0]) * (c[1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (
            c[0] - p[:, 0]
        )
        return out

    s1, s2, s3 = side(a, b), side(b, d), side(d, a)
    return bool(np.any(((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))))
