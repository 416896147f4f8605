"""Walls with relief: heightfields over a plane, ray-cast exactly by safeguarded Newton.

A relief wall is a plane (the *base*: through ``(0, 0, z0)``, turned by ``yaw`` about
the vertical axis) displaced along its normal by a height ``h(u, v)`` of the in-plane
coordinates (u right, v down, heights positive away from the projector). A ray meets it
where ``F(t) = w(t) - h(u(t), v(t)) = 0``; while the relief's slope along the ray is
below the ray's steepness toward the wall, ``F`` increases monotonically, so the root
is unique and Newton's method inside the bracket given by the heights' range (a
bisection step whenever Newton leaves it) finds it to rounding error.

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
        """Ray parameter t (...) of the hit; NaN where the ray does not go toward the wall."""
        o = self.to_wall(np.asarray(origins, dtype=np.float64))
        d = np.asarray(dirs, dtype=np.float64) @ self._frame().T
        lo_h, hi_h = self.span()
        toward = d[..., 2] > 1e-12
        dw = np.where(toward, d[..., 2], 1.0)
        lo = (lo_h - o[..., 2]) / dw
        hi = (hi_h - o[..., 2]) / dw
        t = np.clip(-o[..., 2] / dw, lo, hi)
        for _ in range(NEWTON_STEPS):
            u = o[..., 0] + t * d[..., 0]
            v = o[..., 1] + t * d[..., 1]
            h, hu, hv = self.height(u, v)
            f = o[..., 2] + t * d[..., 2] - h
            # F grows with t: a root lies above t where F < 0
            lo = np.where(f < 0, t, lo)
            hi = np.where(f > 0, t, hi)
            slope = d[..., 2] - hu * d[..., 0] - hv * d[..., 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                newton = t - f / slope
            inside = (slope > 0) & (newton > lo) & (newton < hi)
            t_new = np.where(inside, newton, 0.5 * (lo + hi))
            done = float(np.max(np.abs(np.where(toward, t_new - t, 0.0)), initial=0.0))
            t = t_new
            if done < NEWTON_TOL:
                break
        return np.where(toward & (t > 1e-9), t, np.nan)


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
