"""Analytic surfaces ray-cast from the projector's centre (frame P).

The surface simulator: each surface answers where a ray from the origin first meets
it, and :func:`simulate_surface` turns that into a :class:`Surface` point map. The
same surfaces serve the viewer renderer and the session simulator.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface


class AnalyticSurface(Protocol):
    """A surface that can be ray-cast exactly."""

    @property
    def name(self) -> str:
        """Name of the surface (a key of ``SURFACES``)."""
        ...

    @property
    def developable(self) -> bool:
        """Whether the surface unrolls onto a plane without stretching."""
        ...

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the first hit with t > 0, NaN where none."""
        ...


def _first_positive(t0: FloatArray, t1: FloatArray) -> FloatArray:
    eps = 1e-9
    a = np.where(t0 > eps, t0, np.nan)
    b = np.where(t1 > eps, t1, np.nan)
    return np.fmin(a, b)


@dataclass(frozen=True)
class Plane:
    """Plane ``n . X = d`` (``n`` unit)."""

    name: str
    normal: tuple[float, float, float]
    d: float
    developable: bool = True

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the hit with t > 0, NaN where none or parallel."""
        n = np.asarray(self.normal)
        den = dirs @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.d - origins @ n) / den
        return np.where((t > 1e-9) & (np.abs(den) > 1e-12), t, np.nan)


@dataclass(frozen=True)
class Corner:
    """Two vertical walls meeting along a vertical crease at (x0, ., z0).

    Concave (the crease is the farthest line, seen from inside a room's corner) when
    ``concave``; each wall makes ``half_angle`` with the view direction.
    """

    name: str
    x0: float
    z0: float
    half_angle: float = np.pi / 4
    concave: bool = True
    developable: bool = True

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the nearer hit on either wall (each on its side of the
        crease), NaN where none.
        """
        # Wall i contains the crease and the horizontal direction (s*sin a, 0, -cos a)*sgn.
        a = self.half_angle
        hits = []
        for side in (-1.0, 1.0):
            tangent = np.array([side * np.sin(a), 0.0, -np.cos(a) if self.concave else np.cos(a)])
            n = np.cross(tangent, [0.0, 1.0, 0.0])
            n /= np.linalg.norm(n)
            d = n @ np.array([self.x0, 0.0, self.z0])
            den = dirs @ n
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (d - origins @ n) / den
            x = origins[..., 0] + t * dirs[..., 0]
            on_side = (x - self.x0) * side >= 0
            hits.append(np.where(on_side & (t > 1e-9), t, np.nan))
        return np.fmin(hits[0], hits[1])


@dataclass(frozen=True)
class Cylinder:
    """Vertical cylinder (axis along y) through (cx, ., cz) with radius r."""

    name: str
    cx: float
    cz: float
    r: float
    concave: bool
    developable: bool = True

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the hit with t > 0, the farther one when concave (seen
        from inside), NaN where none.
        """
        ox = origins[..., 0] - self.cx
        oz = origins[..., 2] - self.cz
        dx, dz = dirs[..., 0], dirs[..., 2]
        a = dx * dx + dz * dz
        b = 2 * (ox * dx + oz * dz)
        c = ox * ox + oz * oz - self.r**2
        return _solve_quadratic(a, b, c, far=self.concave)


@dataclass(frozen=True)
class Sphere:
    """Sphere with centre ``c`` and radius ``r``; concave = seen from inside."""

    name: str
    c: tuple[float, float, float]
    r: float
    concave: bool
    developable: bool = False

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the hit with t > 0, the farther one when concave (seen
        from inside), NaN where none.
        """
        o = origins - np.asarray(self.c)
        a = np.sum(dirs * dirs, axis=-1)
        b = 2 * np.sum(o * dirs, axis=-1)
        c = np.sum(o * o, axis=-1) - self.r**2
        return _solve_quadratic(a, b, c, far=self.concave)


@dataclass(frozen=True)
class Bowl:
    """Paraboloid dish ``z = z0 - k (x^2 + y^2)`` opening toward the projector."""

    name: str
    z0: float
    k: float
    developable: bool = False

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the first hit with t > 0, NaN where none."""
        ox, oy, oz = origins[..., 0], origins[..., 1], origins[..., 2]
        dx, dy, dz = dirs[..., 0], dirs[..., 1], dirs[..., 2]
        # k((ox+t dx)^2 + (oy+t dy)^2) + (oz + t dz) - z0 = 0
        a = self.k * (dx * dx + dy * dy)
        b = 2 * self.k * (ox * dx + oy * dy) + dz
        c = self.k * (ox * ox + oy * oy) + oz - self.z0
        return _solve_quadratic(a, b, c, far=False)


def _solve_quadratic(a: FloatArray, b: FloatArray, c: FloatArray, *, far: bool) -> FloatArray:
    """Smallest positive root of a t^2 + b t + c (largest when ``far``), NaN if none."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c = np.asarray(c, dtype=np.float64)
    disc = b * b - 4 * a * c
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    # numerically stable roots; a may be 0 (linear case)
    q = -0.5 * (b + np.copysign(sq, b))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(np.abs(a) > 1e-15, q / a, np.nan)
        r2 = np.where(np.abs(q) > 1e-15, c / q, np.nan)
    r1 = np.where(ok, r1, np.nan)
    r2 = np.where(ok, r2, np.nan)
    if far:
        a1 = np.where(r1 > 1e-9, r1, np.nan)
        a2 = np.where(r2 > 1e-9, r2, np.nan)
        return np.fmax(a1, a2)
    return _first_positive(r1, r2)


def _tilted(angle_deg: float, dist: float) -> Plane:
    a = np.deg2rad(angle_deg)
    n = (float(np.sin(a)), 0.0, -float(np.cos(a)))
    return Plane("tilted", n, float(np.dot(n, (0.0, 0.0, dist))))


SURFACES: dict[str, AnalyticSurface] = {
    s.name: s
    for s in (
        Plane("plane", (0.0, 0.0, -1.0), -1.5),
        _tilted(35.0, 1.5),
        Corner("corner", x0=0.13, z0=1.8),
        Cylinder("cylinder-concave", cx=0.0, cz=0.45, r=1.25, concave=True),
        Cylinder("cylinder-convex", cx=0.0, cz=2.3, r=0.75, concave=False),
        Sphere("sphere-concave", (0.0, 0.0, 0.5), 1.2, concave=True),
        Sphere("sphere-convex", (0.05, 0.0, 2.2), 0.62, concave=False),
        Bowl("bowl", z0=1.9, k=0.9),
    )
}

DEVELOPABLE = tuple(n for n, s in SURFACES.items() if s.developable)
NON_DEVELOPABLE = tuple(n for n, s in SURFACES.items() if not s.developable)


def get_surface(name: str) -> AnalyticSurface:
    """The built-in surface called ``name``; an :class:`InputError` listing them if none is."""
    try:
        return SURFACES[name]
    except KeyError:
        raise InputError(
            f"unknown surface {name!r}; built-in surfaces: {', '.join(SURFACES)}"
        ) from None


def ray_cast(surface: AnalyticSurface, origin: FloatArray, dirs: FloatArray) -> FloatArray:
    """First hit points (..., 3) of rays from ``origin`` along ``dirs``; NaN where none."""
    origins = np.broadcast_to(np.asarray(origin, dtype=np.float64), dirs.shape)
    t = surface.intersect(origins, dirs)
    return origins + t[..., None] * dirs


def simulate_surface(
    surface: AnalyticSurface | str,
    projector: Projector | None = None,
    *,
    step: int = 1,
) -> Surface:
    """The Surface a perfect scanner would measure, at every ``step``-th pixel."""
    s = get_surface(surface) if isinstance(surface, str) else surface
    p = projector or Projector.default()
    if step == 1:
        uv = p.pixel_grid()
    else:
        xs = np.linspace(0, p.width - 1, (p.width - 1) // step + 1)
        ys = np.linspace(0, p.height - 1, (p.height - 1) // step + 1)
        uv = np.stack(np.meshgrid(xs, ys), axis=-1)
    pts = ray_cast(s, np.zeros(3), p.rays(uv))
    return Surface(pts.astype(np.float32), p, {"source": "analytic", "name": s.name})
