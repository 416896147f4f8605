"""Analytic surfaces ray-cast from the projector's centre (frame P).

The surface simulator: each surface answers where a ray from the origin first meets
it, and :func:`simulate_surface` turns that into a :class:`Surface` point map. The
same surfaces serve the viewer renderer and the session simulator.

Besides the smooth ones (planes, a corner, cylinders, spheres, a bowl) there are the
hard cases of the paper and beyond it (:mod:`adaproj_edge.geometry.relief`): a
cylindrical wall standing on a floor (a curved crease, the paper's Figures 9 and 10),
a wall meeting a cone along a ruling (Figure 11), relief of several scales on a wall
and corrugated walls whose waves are as fine as the warp grid or finer. Every surface
names its smooth patches (:meth:`AnalyticSurface.patch`), so a scorer knows where the
map is not differentiable.

This file is about 420 lines on purpose: it is the catalogue of surfaces, each a small
class with the same three methods, and the table that names them; the relief surfaces,
whose geometry is longer, are in :mod:`adaproj_edge.geometry.relief`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.relief import Bumps, Waves
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

    @property
    def grid_smooth(self) -> bool:
        """Smooth at the scale of the default 20x20 warp grid (no crease other than a
        straight one, no detail finer than a few grid cells)."""
        ...

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the first hit with t > 0, NaN where none."""
        ...

    def patch(self, points: FloatArray) -> IntArray:
        """Label (...,) of the smooth patch each surface point (..., 3) lies on: the map
        onto the surface is differentiable only within a patch."""
        ...


def single_patch(points: FloatArray) -> IntArray:
    """Every point on patch 0 (a surface without creases)."""
    return np.zeros(np.shape(points)[:-1], dtype=np.intp)


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
    grid_smooth: bool = True

    def patch(self, points: FloatArray) -> IntArray:
        """Label (...,) of the smooth patch of each point (..., 3): all 0, one patch."""
        return single_patch(points)

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
    grid_smooth: bool = True

    def patch(self, points: FloatArray) -> IntArray:
        """Wall 0 left of the crease, wall 1 right of it."""
        return (points[..., 0] >= self.x0).astype(np.intp)

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
    grid_smooth: bool = True

    def patch(self, points: FloatArray) -> IntArray:
        """Label (...,) of the smooth patch of each point (..., 3): all 0, one patch."""
        return single_patch(points)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the hit with t > 0, the farther one when concave (seen
        from inside), NaN where none.
        """
        return vertical_cylinder(origins, dirs, (self.cx, self.cz, self.r), far=self.concave)


@dataclass(frozen=True)
class Sphere:
    """Sphere with centre ``c`` and radius ``r``; concave = seen from inside."""

    name: str
    c: tuple[float, float, float]
    r: float
    concave: bool
    developable: bool = False
    grid_smooth: bool = True

    def patch(self, points: FloatArray) -> IntArray:
        """Label (...,) of the smooth patch of each point (..., 3): all 0, one patch."""
        return single_patch(points)

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
    grid_smooth: bool = True

    def patch(self, points: FloatArray) -> IntArray:
        """Label (...,) of the smooth patch of each point (..., 3): all 0, one patch."""
        return single_patch(points)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the first hit with t > 0, NaN where none."""
        ox, oy, oz = origins[..., 0], origins[..., 1], origins[..., 2]
        dx, dy, dz = dirs[..., 0], dirs[..., 1], dirs[..., 2]
        # k((ox+t dx)^2 + (oy+t dy)^2) + (oz + t dz) - z0 = 0
        a = self.k * (dx * dx + dy * dy)
        b = 2 * self.k * (ox * dx + oy * dy) + dz
        c = self.k * (ox * ox + oy * oy) + oz - self.z0
        return _solve_quadratic(a, b, c, far=False)


@dataclass(frozen=True)
class CylinderFloor:
    """A half cylinder (vertical axis through (cx, ., cz), radius r, its far half, seen
    from inside) standing on a floor ``y = floor`` (y down): the paper's Figures 9 and
    10. The wall meets the floor along a circle, a curved crease; the floor runs under
    the cylinder and on in front of it."""

    name: str
    cx: float
    cz: float
    r: float
    floor: float
    developable: bool = False
    grid_smooth: bool = False

    def patch(self, points: FloatArray) -> IntArray:
        """The wall 0, the floor 1 (whichever the point lies nearer to)."""
        radial = np.hypot(points[..., 0] - self.cx, points[..., 2] - self.cz)
        return (np.abs(points[..., 1] - self.floor) < np.abs(radial - self.r)).astype(np.intp)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the nearer hit on the wall or the floor (each within
        its own part), NaN where none."""
        t_wall = vertical_cylinder(origins, dirs, (self.cx, self.cz, self.r), far=True)
        ox = origins[..., 0] - self.cx
        oz = origins[..., 2] - self.cz
        dx, dz = dirs[..., 0], dirs[..., 2]
        y_wall = origins[..., 1] + t_wall * dirs[..., 1]
        z_wall = oz + t_wall * dz
        t_wall = np.where((y_wall <= self.floor) & (z_wall >= 0.0), t_wall, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_floor = (self.floor - origins[..., 1]) / dirs[..., 1]
            fx = ox + t_floor * dx
            fz = oz + t_floor * dz
            inside = (fx * fx + fz * fz <= self.r**2) | (fz < 0.0)  # under it, or in front
            t_floor = np.where(np.isfinite(t_floor) & (t_floor > 1e-9) & inside, t_floor, np.nan)
        return np.fmin(t_wall, t_floor)


@dataclass(frozen=True)
class ConeWall:
    """A plane wall ``z = z0`` left of ``x = x0`` meeting a cone along one of its
    rulings, the vertical line through (x0, ., z0) (the paper's Figure 11).

    The cone's apex lies on that line at height ``apex_y``; its axis leans from the
    vertical by the half-angle ``alpha`` toward the horizontal direction at ``turn``
    from the wall's normal (away from the projector), so the cone leaves the wall at
    the angle ``turn`` and bends away. The crease is straight and the whole surface
    develops onto a plane.
    """

    name: str
    x0: float
    z0: float
    apex_y: float
    alpha: float
    turn: float
    developable: bool = True
    grid_smooth: bool = True

    def _axis(self) -> FloatArray:
        b = np.array([np.sin(self.turn), 0.0, np.cos(self.turn)])
        axis: FloatArray = np.cos(self.alpha) * np.array([0.0, 1.0, 0.0]) + np.sin(self.alpha) * b
        return axis

    def patch(self, points: FloatArray) -> IntArray:
        """The wall 0, the cone 1."""
        return (points[..., 0] > self.x0).astype(np.intp)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the nearer hit on the wall or the cone (each on its
        side of the ruling they meet along), NaN where none."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t_wall = (self.z0 - origins[..., 2]) / dirs[..., 2]
        x_wall = origins[..., 0] + t_wall * dirs[..., 0]
        t_wall = np.where((t_wall > 1e-9) & (x_wall <= self.x0), t_wall, np.nan)
        axis = self._axis()
        w = origins - np.array([self.x0, self.apex_y, self.z0])
        c2 = np.cos(self.alpha) ** 2
        da, wa = dirs @ axis, w @ axis
        a = da * da - c2 * np.sum(dirs * dirs, axis=-1)
        b = 2 * (wa * da - c2 * np.sum(w * dirs, axis=-1))
        c = wa * wa - c2 * np.sum(w * w, axis=-1)
        best = np.full(np.shape(t_wall), np.nan)
        for far in (False, True):  # the nearer root on the cone's piece
            t = _solve_quadratic(a, b, c, far=far)
            x = origins + t[..., None] * dirs
            on = ((x - np.array([self.x0, self.apex_y, self.z0])) @ axis > 0) & (
                x[..., 0] > self.x0
            )
            best = np.fmin(best, np.where(on, t, np.nan))
        out: FloatArray = np.fmin(t_wall, best)
        return out


def vertical_cylinder(
    origins: FloatArray, dirs: FloatArray, circle: tuple[float, float, float], *, far: bool
) -> FloatArray:
    """Ray parameter (...) of the hit with the vertical cylinder ``circle`` = (cx, cz, r):
    the nearest positive one, the farthest when ``far`` (seen from inside); NaN if none."""
    cx, cz, r = circle
    ox = origins[..., 0] - cx
    oz = origins[..., 2] - cz
    dx, dz = dirs[..., 0], dirs[..., 2]
    a = dx * dx + dz * dz
    return _solve_quadratic(a, 2 * (ox * dx + oz * dz), ox * ox + oz * oz - r * r, far=far)


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


# bumps (u, v, sigma, height) of four sizes, from about two grid cells (at 20x20 and
# 1.5 m a cell is 5.4 x 3.4 cm) down to a quarter of one, slopes up to ~0.35
RELIEF_BUMPS = (
    (-0.28, -0.12, 0.08, -0.045),
    (0.22, 0.14, 0.07, 0.035),
    (0.05, -0.05, 0.04, -0.022),
    (-0.3, 0.17, 0.035, 0.02),
    (0.36, -0.18, 0.04, -0.022),
    (-0.08, 0.2, 0.02, -0.011),
    (0.2, -0.2, 0.02, 0.011),
    (-0.42, 0.0, 0.018, -0.01),
    (0.14, 0.02, 0.01, -0.0055),
    (-0.15, -0.22, 0.01, 0.0055),
    (0.42, 0.12, 0.009, -0.005),
)


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
        CylinderFloor("cylinder-floor", cx=0.0, cz=1.1, r=0.7, floor=0.25),
        ConeWall("cone-wall", x0=-0.12, z0=1.6, apex_y=-1.4, alpha=0.3, turn=0.35),
        Bumps("bumps", 1.5, RELIEF_BUMPS),
        Waves("waves", 1.6, wavelength=0.12, amplitude=0.009, yaw=0.3),
        Waves("waves-fine", 1.5, wavelength=0.045, amplitude=0.003, direction=0.5),
    )
}

# the surfaces smooth at the grid's scale, developable or not, and the hard cases
DEVELOPABLE = tuple(n for n, s in SURFACES.items() if s.developable and s.grid_smooth)
NON_DEVELOPABLE = tuple(n for n, s in SURFACES.items() if not s.developable and s.grid_smooth)
FINE_DETAIL = tuple(n for n, s in SURFACES.items() if not s.grid_smooth)


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
