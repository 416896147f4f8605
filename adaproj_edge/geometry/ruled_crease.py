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

from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray

NEWTON_STEPS = 8
REACH = 2.0  # the crease must lie within this many triangle sizes of the triangle
MIN_BENT_POINTS = 9  # a bent side is fitted from at least this many points
OUTLIERS = 0.2  # ... of which at most this share may be left out


@dataclass(frozen=True)
class SidePatch:
    """One side near the crease: the points ``origin + u t + w s + h(u, w) n`` with
    ``h = c0 + c1 u + c2 w + c3 u^2 + c4 u w + c5 w^2``."""

    origin: FloatArray
    frame: FloatArray  # (3, 3) rows t, s, n
    coef: FloatArray  # (6,)

    def height(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``n . (X - origin) - h(u, w)`` of points (K, 3) (K,), and its gradient (K, 3)."""
        q = (points - self.origin) @ self.frame.T  # (K, 3): u, w, y
        u, w, y = q[:, 0], q[:, 1], q[:, 2]
        c = self.coef
        f = y - (c[0] + c[1] * u + c[2] * w + c[3] * u * u + c[4] * u * w + c[5] * w * w)
        du = -(c[1] + 2 * c[3] * u + c[4] * w)
        dw = -(c[2] + c[4] * u + 2 * c[5] * w)
        grad = du[:, None] * self.frame[0] + dw[:, None] * self.frame[1] + self.frame[2]
        return f, grad


def side_patch(
    points: FloatArray, origin: FloatArray, normal: FloatArray, tol: float
) -> SidePatch | None:
    """The :class:`SidePatch` of a side's surface ``points`` (K, 3) in the frame of its
    plane's ``normal`` at ``origin``: a plane where one explains them to within ``tol``,
    else the quadratic. A point farther than ``tol`` from the first fit (a triangle
    that reaches a hair across the crease lends it a point of the other side) is left
    out of a second one, up to :data:`OUTLIERS` of them. None with too few points, or
    if the side is not explained to within ``tol`` so."""
    n = normal / np.linalg.norm(normal)
    t = np.cross(np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0, 0]), n)
    t /= np.linalg.norm(t)
    frame = np.stack([t, np.cross(n, t), n])
    q = (points - origin) @ frame.T
    u, w, y = q[:, 0], q[:, 1], q[:, 2]
    lin = np.stack([np.ones_like(u), u, w], axis=1)
    quad = np.concatenate([lin, np.stack([u * u, u * w, w * w], axis=1)], axis=1)
    for basis, least in ((lin, 3), (quad, MIN_BENT_POINTS)):
        use = np.ones(y.size, dtype=bool)
        for _ in range(2):
            if use.sum() < least:
                break
            coef, _, rank, _ = np.linalg.lstsq(basis[use], y[use], rcond=None)
            off = np.abs(basis @ coef - y)
            if rank == basis.shape[1] and np.all(off[use] <= tol):
                return SidePatch(origin, frame, np.concatenate([coef, np.zeros(6 - coef.size)]))
            use = off <= tol
            if y.size - use.sum() > OUTLIERS * y.size:
                break
    return None


def meet(a: SidePatch, b: SidePatch, start: FloatArray, d: FloatArray) -> FloatArray | None:
    """The point (3,) where patches ``a`` and ``b`` meet in the plane through ``start``
    across the direction ``d`` (unit), from ``start`` by Newton's method; None if it
    does not converge."""
    x = start.astype(np.float64).copy()
    for _ in range(NEWTON_STEPS):
        fa, ga = a.height(x[None])
        fb, gb = b.height(x[None])
        jac = np.stack([ga[0], gb[0], d])
        if abs(np.linalg.det(jac)) < 1e-12:
            return None
        x = x - np.linalg.solve(jac, np.array([fa[0], fb[0], (x - start) @ d]))
    fa, _ = a.height(x[None])
    fb, _ = b.height(x[None])
    if not np.all(np.isfinite(x)) or max(abs(fa[0]), abs(fb[0])) > 1e-9:
        return None
    return x


def crease_planes(
    a: SidePatch, b: SidePatch, centre: FloatArray, d: FloatArray, size: float, straight: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
    """The planes (na, pa, nb, pb) tangent to patches ``a`` and ``b`` where they meet
    across the triangle at ``centre`` (size ``size``, crease roughly along ``d``),
    normals facing as the patches' planes do; None if they do not meet within
    :data:`REACH` sizes, or along a line: the crease at half a size either side must
    lie within ``straight`` of the line the planes meet along."""
    o = meet(a, b, centre, d)
    if o is None or float(np.linalg.norm(o - centre)) > REACH * size:
        return None
    _, ga = a.height(o[None])
    _, gb = b.height(o[None])
    na, nb = ga[0] / np.linalg.norm(ga[0]), gb[0] / np.linalg.norm(gb[0])
    line = np.cross(na, nb)
    line /= np.linalg.norm(line)
    for side in (-0.5, 0.5):
        p = meet(a, b, o + side * size * line, line)
        if p is None:
            return None
        off = (p - o) - ((p - o) @ line) * line
        if float(np.linalg.norm(off)) > straight:
            return None
    return na, o, nb, o.copy()
