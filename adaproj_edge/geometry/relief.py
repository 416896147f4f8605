"""Walls with relief: heightfields over a plane, ray-cast exactly by safeguarded Newton.

A relief wall is a plane (the *base*: through ``(0, 0, z0)``, turned by ``yaw`` about
the vertical axis) displaced along its normal by a height ``h(u, v)`` of the in-plane
coordinates (u right, v down, heights positive away from the projector). A ray meets it
where ``F(t) = w(t) - h(u(t), v(t)) = 0``; while the relief's slope along the ray is
below the ray's steepness toward the wall, ``F`` increases monotonically, so the root
is unique and Newton's method inside the bracket given by the heights' range (a
bisection step whenever Newton leaves it) finds it to rounding error, each ray
iterating until its own step is below :data:`NEWTON_TOL`.

* :class:`Bumps` - round bumps and dents of several sizes (doubly curved: not
  developable), from larger than a grid cell to a quarter of one.
* :class:`Waves` - a corrugated wall, ``h = a sin(k (u cos phi + v sin phi))``: every
  ridge is a straight line, so the wall develops onto a plane exactly; its waves can
  be finer than the warp grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray

NEWTON_STEPS = 60
NEWTON_TOL = 1e-13  # metres along the ray


class _Relief:
    """Ray casting shared by the relief walls (``z0``, ``yaw``, ``height``, ``span``)."""

    z0: float
    yaw: float

    def height(self, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Height (...) of the wall over the base plane and its gradient (du, dv)."""
        raise NotImplementedError

    def span(self) -> tuple[float, float]:
        """Lowest and highest height anywhere (bounds of the Newton bracket)."""
        raise NotImplementedError

    def _frame(self) -> FloatArray:
        """Rows: the base plane's u, v, w axes in frame P."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])

    def to_wall(self, points: FloatArray) -> FloatArray:
        """Points (..., 3) of frame P in the base plane's (u, v, w) coordinates."""
        out: FloatArray = (points - np.array([0.0, 0.0, self.z0])) @ self._frame().T
        return out

    def patch(self, points: FloatArray) -> IntArray:
        """One smooth patch."""
        return np.zeros(np.shape(points)[:-1], dtype=np.intp)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...) of the hit; NaN where the ray does not go toward the wall.

        Each ray stops once its own step is below :data:`NEWTON_TOL`: the iterations
        run on the rays still moving only (a few rays that need bisection steps no
        longer keep every other ray iterating)."""
        o = self.to_wall(np.asarray(origins, dtype=np.float64))
        d = np.asarray(dirs, dtype=np.float64) @ self._frame().T
        lo_h, hi_h = self.span()
        toward = d[..., 2] > 1e-12
        dw = np.where(toward, d[..., 2], 1.0)
        t_all = np.clip(-o[..., 2] / dw, (lo_h - o[..., 2]) / dw, (hi_h - o[..., 2]) / dw)
        # the rays toward the wall, flat; each array below holds the rays still moving
        idx = np.flatnonzero(toward)
        t_flat = t_all.reshape(-1)
        ox, oy, oz = (o[..., k].reshape(-1)[idx] for k in range(3))
        dx, dy, dz = (d[..., k].reshape(-1)[idx] for k in range(3))
        lo, hi = (lo_h - oz) / dz, (hi_h - oz) / dz
        t = t_flat[idx]
        for _ in range(NEWTON_STEPS):
            if idx.size == 0:
                break
            h, hu, hv = self.height(ox + t * dx, oy + t * dy)
            f = oz + t * dz - h
            # F grows with t: a root lies above t where F < 0
            lo = np.where(f < 0, t, lo)
            hi = np.where(f > 0, t, hi)
            slope = dz - hu * dx - hv * dy
            with np.errstate(divide="ignore", invalid="ignore"):
                newton = t - f / slope
            # a Newton step below the tolerance is the root (it may round onto a bound)
            close = np.abs(newton - t) < NEWTON_TOL
            inside = close | ((slope > 0) & (newton > lo) & (newton < hi))
            t_new = np.where(inside, newton, 0.5 * (lo + hi))
            t_flat[idx] = t_new
            moving = ~(np.abs(t_new - t) < NEWTON_TOL)
            idx, t, lo, hi = idx[moving], t_new[moving], lo[moving], hi[moving]
            ox, oy, oz, dx, dy, dz = (a[moving] for a in (ox, oy, oz, dx, dy, dz))
        return np.where(toward & (t_all > 1e-9), t_all, np.nan)


@dataclass(frozen=True)
class Bumps(_Relief):
    """A wall at depth ``z0`` with Gaussian bumps ``(u, v, sigma, height)`` (metres;
    negative heights come toward the projector)."""

    name: str
    z0: float
    bumps: tuple[tuple[float, float, float, float], ...]
    yaw: float = 0.0
    developable: bool = False
    grid_smooth: bool = False

    def height(self, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Height off the wall (m) at wall coordinates ``u``, ``v`` (...,) and its
        derivatives along u and v."""
        h = np.zeros(np.shape(u))
        hu = np.zeros(np.shape(u))
        hv = np.zeros(np.shape(u))
        for cu, cv, sigma, a in self.bumps:
            du, dv = u - cu, v - cv
            g = a * np.exp(-(du * du + dv * dv) / (2 * sigma * sigma))
            h += g
            hu -= g * du / (sigma * sigma)
            hv -= g * dv / (sigma * sigma)
        return h, hu, hv

    def span(self) -> tuple[float, float]:
        """The lowest and highest the relief reaches off the wall, m."""
        heights = [b[3] for b in self.bumps]
        return sum(min(a, 0.0) for a in heights), sum(max(a, 0.0) for a in heights)


@dataclass(frozen=True)
class Waves(_Relief):
    """A corrugated wall at depth ``z0``: ``h = amplitude sin(2 pi s / wavelength)``
    along the in-plane direction ``s = u cos(direction) + v sin(direction)``."""

    name: str
    z0: float
    wavelength: float
    amplitude: float
    direction: float = 0.0
    yaw: float = 0.0
    developable: bool = True
    grid_smooth: bool = False

    def height(self, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Height off the wall (m) at wall coordinates ``u``, ``v`` (...,) and its
        derivatives along u and v."""
        k = 2 * np.pi / self.wavelength
        cu, cv = np.cos(self.direction), np.sin(self.direction)
        phase = k * (u * cu + v * cv)
        slope = self.amplitude * k * np.cos(phase)
        return self.amplitude * np.sin(phase), slope * cu, slope * cv

    def span(self) -> tuple[float, float]:
        """The lowest and highest the relief reaches off the wall, m."""
        return -abs(self.amplitude), abs(self.amplitude)
