"""A straight crease whose sides are curved developable surfaces: its exact planes.

A plane wall meeting a cone (or a cylinder) along one of its rulings has a straight
crease, but the cone side bends away from any plane: the planes of its corners are
tangent to it a cell away from the crease, and the line where such a plane meets the
wall is not the crease. Rotated about that line, the cone side lands shifted by about
``kappa s^2 / 2 tan(angle / 2)`` (s: the corner's distance from the crease) - a few
tenths of a percent of a cell, enough to spoil an exact display.

So each side is fitted, from the surface points of its smooth triangles next to the
crease, with a quadratic height over its plane (:class:`SidePatch`; a plane where its
points lie on one). The two patches meet along the crease; where it is straight across
the triangle (the sides meet along a line, not a curve as a cylinder standing on a floor
does), the patches' tangent planes at the crease are the planes its triangles unfold
with - exact to second order, as a chord triangle is - and the rotation is about the
crease itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray

NEWTON_STEPS = 8
REACH = 2.0  # the crease must lie within this many triangle sizes of the triangle
MIN_BENT_POINTS = 9  # a bent side is fitted from at least this many points
# a probe this many pixels or less from the crease is sampled across it (the point map
# is interpolated between pixels on either side, on neither patch): not held to them
ACROSS_PIXELS = 2.0
OUTLIERS = 0.2  # ... of which at most this share may be left out
FIT_ROUNDS = 4  # fits, each leaving out the points farthest off the one before
# a crease's candidates are tried until this many (plus two per one found) failed: a
# surface rough all over (waves finer than the grid: ~1000 candidates, none a straight
# crease, 0.3 ms each) is not a few straight creases; a cone wall's fail 0-11 times
MISSES = 24
# ... and those its corners' planes explain (a curved side: a curved crease's too) until
# this many were not (a cylinder on a floor: every one of its crease's, ~0.8 ms each; a
# cone wall's fail 0-12 times, among 10-60 found; seed 1 case 107 changes at 2)
BENT_MISSES = 4
# ... and a candidate tried again with a wider cloud (its first fit failed) until this
# many such retries failed (plus two per crease found): all of a cone wall's retries
# come after tens of its triangles were found (seed 3 cases 26, 164: 30 / 23 retries,
# 92 / 118 found), while sensed depth with no crease retried every candidate (68 per
# replay of tools/bench_app.py's session, none found)
WIDE_MISSES = 2


@dataclass(frozen=True)
class SidePatch:
    """One side near the crease: the points ``origin + u t + w s + h(u, w) n`` with
    ``h = c0 + c1 u + c2 w + c3 u^2 + c4 u w + c5 w^2``."""

    origin: FloatArray
    frame: FloatArray  # (3, 3) rows t, s, n
    coef: FloatArray  # (6,)

    def height(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``n . (X - origin) - h(u, w)`` of points (K, 3) (K,), and its gradient (K, 3)."""
        u, w, y = self._local(points)
        c = self.coef
        du = -(c[1] + 2 * c[3] * u + c[4] * w)
        dw = -(c[2] + c[4] * u + 2 * c[5] * w)
        grad = du[:, None] * self.frame[0] + dw[:, None] * self.frame[1] + self.frame[2]
        return self._off(u, w, y), grad

    def residual(self, points: FloatArray) -> FloatArray:
        """The first of :meth:`height` alone (K,), without the gradient (the crease search
        asks for it four times per candidate)."""
        return self._off(*self._local(points))

    def _local(self, points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``u, w, y`` (K,) of points (K, 3) in the patch's frame."""
        q = (points - self.origin) @ self.frame.T  # (K, 3): u, w, y
        return q[:, 0], q[:, 1], q[:, 2]

    def _off(self, u: FloatArray, w: FloatArray, y: FloatArray) -> FloatArray:
        """``y - h(u, w)``."""
        c = self.coef
        out: FloatArray = y - (
            c[0] + c[1] * u + c[2] * w + c[3] * u * u + c[4] * u * w + c[5] * w * w
        )
        return out


def side_patch(
    points: FloatArray, origin: FloatArray, normal: FloatArray, tol: float
) -> SidePatch | None:
    """The :class:`SidePatch` of a side's surface ``points`` (K, 3) in the frame of its
    plane's ``normal`` at ``origin``: a plane where one explains them to within ``tol``,
    else the quadratic. A point farther than ``tol`` from the first fit (a triangle
    that reaches a hair across the crease lends it a point of the other side) is left
    out of a second one, up to :data:`OUTLIERS` of them. None with too few points, or
    if the side is not explained to within ``tol`` so."""
    if points.shape[0] < 3:
        return None
    n = normal / np.sqrt(normal @ normal)
    # t: across n, from the x or y axis (whichever is farther from n)
    t = np.array([n[2], 0.0, -n[0]]) if abs(n[1]) < 0.9 else np.array([0.0, -n[2], n[1]])
    t /= np.sqrt(t @ t)
    frame = np.array(  # (np.array: the same rows as np.stack, at a third of its cost)
        [t, [n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]], n]
    )
    q = (points - origin) @ frame.T
    u, w, y = q[:, 0], q[:, 1], q[:, 2]
    # (filled column by column: a few calls fewer than np.stack, the same array; this
    # runs for every crease candidate tried, tens per mesh)
    quad = np.empty((y.size, 6))
    quad[:, 0], quad[:, 1], quad[:, 2] = 1.0, u, w
    quad[:, 3], quad[:, 4], quad[:, 5] = u * u, u * w, w * w
    for cols, least in ((3, 3), (6, MIN_BENT_POINTS)):
        basis = quad[:, :cols]
        use = np.ones(y.size, dtype=bool)
        kept = y.size
        for _ in range(FIT_ROUNDS):
            if kept < least:
                break
            coef = _least_squares(basis[use], y[use])
            if coef is None:
                break
            off = np.abs(basis @ coef - y)
            # (the largest is within tol exactly when all are: NaN fails both)
            worst = float(off[use].max())
            if worst <= tol:
                return SidePatch(origin, frame, np.concatenate([coef, np.zeros(6 - cols)]))
            # the points farthest off left out (a few far ones, from a triangle that
            # reaches across the crease, pull the first fit off the others too)
            use &= off <= max(tol, 0.5 * worst)
            kept = int(np.count_nonzero(use))
            if y.size - kept > OUTLIERS * y.size:
                break
    return None


def _least_squares(a: FloatArray, y: FloatArray) -> FloatArray | None:
    """The least-squares solution of ``a x = y`` by its normal equations (columns
    scaled to unit size first), None where ``a`` has not full rank."""
    scale = np.sqrt(np.einsum("ij,ij->j", a, a))
    if not (scale > 0).all():
        return None
    b = a / scale
    g = b.T @ b
    if np.linalg.det(g) < 1e-12:  # (1 for orthogonal columns)
        return None
    out: FloatArray = np.linalg.solve(g, b.T @ y) / scale
    return out


Vec = tuple[float, float, float]


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


class _Plain:
    """A :class:`SidePatch` in plain floats, evaluated at one point at a time (the few
    Newton steps cost less so than as numpy calls)."""

    def __init__(self, patch: SidePatch) -> None:
        o, f, c = patch.origin, patch.frame, patch.coef
        self.o: Vec = (float(o[0]), float(o[1]), float(o[2]))
        self.t: Vec = (float(f[0, 0]), float(f[0, 1]), float(f[0, 2]))
        self.s: Vec = (float(f[1, 0]), float(f[1, 1]), float(f[1, 2]))
        self.n: Vec = (float(f[2, 0]), float(f[2, 1]), float(f[2, 2]))
        self.c = [float(v) for v in c]

    def height(self, x: Vec) -> tuple[float, Vec]:
        # (written out: called a few thousand times per mesh with a crease; the same
        # operations in the same order as SidePatch.height)
        o, t, s, n, c = self.o, self.t, self.s, self.n, self.c
        q0, q1, q2 = x[0] - o[0], x[1] - o[1], x[2] - o[2]
        u = q0 * t[0] + q1 * t[1] + q2 * t[2]
        w = q0 * s[0] + q1 * s[1] + q2 * s[2]
        y = q0 * n[0] + q1 * n[1] + q2 * n[2]
        f = y - (c[0] + c[1] * u + c[2] * w + c[3] * u * u + c[4] * u * w + c[5] * w * w)
        du = -(c[1] + 2 * c[3] * u + c[4] * w)
        dw = -(c[2] + c[4] * u + 2 * c[5] * w)
        return f, (
            du * t[0] + dw * s[0] + n[0],
            du * t[1] + dw * s[1] + n[1],
            du * t[2] + dw * s[2] + n[2],
        )


def _meet(a: _Plain, b: _Plain, start: Vec, d: Vec) -> Vec | None:
    x = start
    d0, d1, d2 = d
    for _ in range(NEWTON_STEPS):
        fa, ga = a.height(x)
        fb, gb = b.height(x)
        # solve [ga; gb; d] dx = -(fa, fb, (x - start) . d) by Cramer's rule
        r0, r1 = -fa, -fb
        r2 = -((x[0] - start[0]) * d0 + (x[1] - start[1]) * d1 + (x[2] - start[2]) * d2)
        a0, a1, a2 = ga
        b0, b1, b2 = gb
        # gb x d, d x ga, ga x gb
        e0, e1, e2 = b1 * d2 - b2 * d1, b2 * d0 - b0 * d2, b0 * d1 - b1 * d0
        f0, f1, f2 = d1 * a2 - d2 * a1, d2 * a0 - d0 * a2, d0 * a1 - d1 * a0
        g0, g1, g2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        det = a0 * e0 + a1 * e1 + a2 * e2
        if abs(det) < 1e-12:
            return None
        dx0 = (r0 * e0 + r1 * f0 + r2 * g0) / det
        dx1 = (r0 * e1 + r1 * f1 + r2 * g1) / det
        dx2 = (r0 * e2 + r1 * f2 + r2 * g2) / det
        x = (x[0] + dx0, x[1] + dx1, x[2] + dx2)
        if abs(fa) + abs(fb) < 1e-13 and max(abs(dx0), abs(dx1), abs(dx2)) < 1e-13:
            break
    fa, _ = a.height(x)
    fb, _ = b.height(x)
    if not (math.isfinite(x[0]) and math.isfinite(x[1]) and math.isfinite(x[2])):
        return None
    if max(abs(fa), abs(fb)) > 1e-9:
        return None
    return x


def meet(a: SidePatch, b: SidePatch, start: FloatArray, d: FloatArray) -> FloatArray | None:
    """The point (3,) where patches ``a`` and ``b`` meet in the plane through ``start``
    across the direction ``d`` (unit), from ``start`` by Newton's method; None if it
    does not converge."""
    x = _meet(_Plain(a), _Plain(b), _vec(start), _vec(d))
    return None if x is None else np.array(x)


def _vec(v: FloatArray) -> Vec:
    return (float(v[0]), float(v[1]), float(v[2]))


def crease_planes(
    a: SidePatch, b: SidePatch, centre: FloatArray, d: FloatArray, size: float, straight: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
    """The planes (na, pa, nb, pb) tangent to patches ``a`` and ``b`` where they meet
    across the triangle at ``centre`` (size ``size``, crease roughly along ``d``),
    normals facing as the patches' planes do; None if they do not meet within
    :data:`REACH` sizes, or along a line: the crease at half a size either side must
    lie within ``straight`` of the line the planes meet along."""
    pa_, pb_ = _Plain(a), _Plain(b)
    o = _meet(pa_, pb_, _vec(centre), _vec(d))
    if o is None:
        return None
    if float(np.linalg.norm(np.array(o) - centre)) > REACH * size:
        return None
    ga, gb = pa_.height(o)[1], pb_.height(o)[1]
    na = np.array(ga) / np.sqrt(_dot(ga, ga))
    nb = np.array(gb) / np.sqrt(_dot(gb, gb))
    line = np.array(_cross(_vec(na), _vec(nb)))  # (as np.cross, in plain floats)
    line /= np.linalg.norm(line)
    ln = _vec(line)
    for side in (-0.5, 0.5):
        start = (o[0] + side * size * ln[0], o[1] + side * size * ln[1], o[2] + side * size * ln[2])
        p = _meet(pa_, pb_, start, ln)
        if p is None:
            return None
        q = (p[0] - o[0], p[1] - o[1], p[2] - o[2])
        along = _dot(q, ln)
        off = (q[0] - along * ln[0], q[1] - along * ln[1], q[2] - along * ln[2])
        if np.sqrt(_dot(off, off)) > straight:
            return None
    at = np.array(o)
    return na, at, nb, at.copy()


def _from_line(
    points: FloatArray, planes: tuple[FloatArray, FloatArray, FloatArray, FloatArray]
) -> FloatArray:
    """Distances (K,) of ``points`` (K, 3) from the line where ``planes`` (na, pa, nb,
    pb; pa on both) meet."""
    line = np.cross(planes[0], planes[2])
    line /= np.linalg.norm(line)
    rel = points - planes[1]
    out: FloatArray = np.linalg.norm(rel - np.outer(rel @ line, line), axis=1)
    return out


def pixel_spans(tri_uv: FloatArray, tri_pts: FloatArray) -> FloatArray:
    """The most (T,) a pixel spans on the surface along an edge of each triangle, with
    pixel corners ``tri_uv`` (T, 3, 2) and surface corners ``tri_pts`` (T, 3, 3)."""
    d_uv = tri_uv - np.roll(tri_uv, 1, axis=1)
    d_pts = tri_pts - np.roll(tri_pts, 1, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        span = np.linalg.norm(d_pts, axis=2) / np.linalg.norm(d_uv, axis=2)
    out: FloatArray = np.max(np.where(np.isfinite(span), span, 0.0), axis=1)
    return out


def _unique(ids: IntArray) -> IntArray:
    """``np.unique`` of a few tens of indices (its calls cost more than the sort)."""
    out = np.sort(ids)
    if out.size > 1:
        out = out[np.concatenate(([True], out[1:] != out[:-1]))]
    return out


def ruled_planes(
    retry: IntArray,
    cand: IntArray,
    tris: IntArray,
    tri_pts: FloatArray,
    normals: FloatArray,
    probes: FloatArray,
    size: FloatArray,
    settled: tuple[NDArray[np.bool_], ...],
    planes: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    pair_a: NDArray[np.bool_],
    lone: IntArray,
    fit: float,
    bent: NDArray[np.bool_],
    pixel: FloatArray | None = None,
) -> IntArray:
    """Of the crease candidates ``retry`` (indices into ``cand``, the triangles of
    ``tris``; ``lone`` / ``pair_a`` their corner groups, as in
    :mod:`~adaproj_edge.geometry.creases`), those that are a straight crease between
    curved sides, explained to ``fit`` of their ``size``; their planes in ``planes``
    (na, pa, nb, pb: (C, 3) each) are replaced, in place, by the sides' tangent planes
    at the crease, and ``lone`` / ``pair_a`` by the corners' sides: each corner's
    patch is the one it lies on. ``settled``: the flat triangles, the smooth ones that are no crease
    candidates and the other smooth ones, whose corners and ``probes`` (3, 4, T) give a
    side its points (each vertex's first kind it has: a cone corner next to the crease
    may have only smooth triangles whose corners' planes differ); where these do not
    explain a candidate, it is tried again with every flat triangle and smooth one that
    is no crease candidate within :data:`REACH` sizes of it (at the mesh's outline a
    corner may have few, or none but rough ones). ``bent`` (as
    ``retry``): the candidate is taken only where a side's patch is bent (its corners'
    planes explain it already, but a side is curved). The candidates are tried in order
    until :data:`MISSES` of them (plus two per one found) were not such a crease, those
    with ``bent`` until :data:`BENT_MISSES` of them (plus two per one found).
    ``pixel`` (T,): the most a pixel spans on each triangle (metres,
    :func:`pixel_spans`); a probe within :data:`ACROSS_PIXELS` of them from the crease
    is not held to the patches (None: every probe is)."""
    na, pa, nb, pb = planes
    # each vertex's triangles of each kind (those of vertex v: table[starts[v]:starts[v + 1]])
    tables = []
    for mask in settled:
        use = np.flatnonzero(mask)
        corner_of = tris[use].ravel()
        order = np.argsort(corner_of, kind="stable")
        starts = np.searchsorted(corner_of[order], np.arange(tris.max() + 2))
        tables.append((use[order // 3], starts.tolist()))  # (read an entry at a time)
    # (the smooth triangles that are no crease candidates, and their centres)
    pool = np.flatnonzero(settled[0] | settled[1])
    pool_at = tri_pts[pool].mean(axis=1)
    found: list[int] = []
    misses = 0
    bent_misses = 0
    wide_misses = 0
    # (a candidate whose sides' corners' triangles do not explain it is tried again
    # with every smooth triangle within reach: at the mesh's outline a corner has few,
    # or none but rough ones)
    queue = [(int(c), bool(b), False) for c, b in zip(retry, bent, strict=True)]
    for c, must_bend, wide in queue:
        if misses >= MISSES + 2 * len(found):
            break
        if must_bend and bent_misses >= BENT_MISSES + 2 * len(found):
            continue
        if wide and wide_misses >= WIDE_MISSES + 2 * len(found):
            continue
        misses += 0 if wide else 1  # (taken back below when it is found)
        bent_misses += int(must_bend and not wide)
        wide_misses += int(wide)
        t = cand[c]
        d = np.array(_cross(_vec(na[c]), _vec(nb[c])))  # (as np.cross, in plain floats)
        d /= np.linalg.norm(d)
        side_b = [lone[c]] if pair_a[c] else [k for k in range(3) if k != lone[c]]
        origin = tri_pts[t].mean(axis=0)
        tol = fit * size[t]
        patches: list[SidePatch] = []
        if wide:  # every smooth triangle within reach, for either side
            gap = pool_at - origin
            within = pool[np.einsum("ij,ij->i", gap, gap) <= (REACH * size[t]) ** 2]
        for n_s, n_o, ks in (
            (na[c], nb[c], [k for k in range(3) if k not in side_b]),
            (nb[c], na[c], side_b),
        ):
            near = []
            for v in tris[t, ks].tolist():  # a vertex's flat triangles where it has any, ...
                for table, starts in tables:
                    if starts[v + 1] > starts[v]:
                        near.append(table[starts[v] : starts[v + 1]])
                        break
            if wide:
                near = [within]
            nbr = _unique(np.concatenate(near)) if near else np.zeros(0, dtype=np.intp)
            nbr_n = normals[:, nbr].T
            nbr = nbr[np.abs(nbr_n @ n_s) > np.abs(nbr_n @ n_o)]
            cloud = np.concatenate(
                [
                    tri_pts[t, ks],
                    tri_pts[nbr].reshape(-1, 3),
                    probes[:, :, nbr].transpose(2, 1, 0).reshape(-1, 3),
                ]
            )
            patch = side_patch(cloud[np.isfinite(cloud).all(axis=1)], origin, n_s, tol)
            if patch is None:
                break
            patches.append(patch)
        if len(patches) < 2:
            queue += [] if wide else [(c, must_bend, True)]
            continue
        ca, cb = patches
        if must_bend and not (np.any(ca.coef[3:] != 0.0) or np.any(cb.coef[3:] != 0.0)):
            continue  # (two planes: the corners' planes are theirs)
        met = crease_planes(ca, cb, origin, d, float(size[t]), tol)
        probe = probes[:, :, t].T
        probe = probe[np.isfinite(probe).all(axis=1)]
        resid = np.minimum(np.abs(ca.residual(probe)), np.abs(cb.residual(probe)))
        if met is not None and pixel is not None:
            # (cells long along the crease put a probe beside it: a cone wall rolled
            # 75 deg, 64 x 8 px cells, the centroid half a pixel past it 3 tolerances
            # off the wall and 4 off the cone: its triangle was left a chord across
            # the crease, a band two cells long where the display blends with it)
            resid = np.where(_from_line(probe, met) <= ACROSS_PIXELS * pixel[t], 0.0, resid)
        # each corner goes with the patch it lies on (one a hair across the crease is
        # left out of its side's fit, and grouped by its plane with the wrong side);
        # with all on one patch the crease misses the triangle
        ha, hb = np.abs(ca.residual(tri_pts[t])), np.abs(cb.residual(tri_pts[t]))
        in_b = np.array([k in side_b for k in range(3)])
        in_b = np.where((ha <= tol) & (hb <= tol), in_b, hb < ha)
        # (a triangle with no probe on the surface is not explained)
        if met is None or resid.size == 0 or resid.max() > tol or in_b.all() or ~in_b.any():
            queue += [] if wide else [(c, must_bend, True)]
            continue
        if in_b[0]:  # (side a is the side of corner 0)
            met, in_b = (met[2], met[3], met[0], met[1]), ~in_b
        lone[c] = int(np.flatnonzero(in_b)[0]) if in_b.sum() == 1 else 0
        pair_a[c] = lone[c] != 0
        na[c], pa[c], nb[c], pb[c] = met
        found.append(int(c))
        bent_misses -= int(must_bend)
        wide_misses -= int(wide)
        misses -= 1
    return np.array(found, dtype=np.intp)
