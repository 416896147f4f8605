"""Random members of every analytic surface class and the checks of issue 13's lines on
them, scored by the independent scorer (``tests/distortion.py``): shared by
``tools/stress_warp.py`` (hundreds of cases) and ``test_random_surfaces.py`` (a fixed
sample in CI). See the tool's docstring for the lines and how cases are drawn.

About 400 lines on purpose: the drawing of every surface class and the checks belong
together (a case is reproduced from its seed and index alone).
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import InputError, WarpError
from adaproj_edge.geometry.analytic import (
    Bowl,
    ConeWall,
    Corner,
    Cylinder,
    CylinderFloor,
    Plane,
    Sphere,
    simulate_surface,
)
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.relief import Bumps, Waves
from adaproj_edge.geometry.rotations import rodrigues
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid
from tests.distortion import Distortion, in_mask, measure, surface_points, visible_fraction
from tests.shown_maps import shown_map

EXACT = 3e-4
EXACT_FINE = 0.005
# the bend kappa h of a cell at which the display of a developable surface is exact to
# 2e-4 (warp/adaptive.py)
BEND_EXACT = 0.1
COVER = 0.9996
CONTENT_SIZES = ((640, 400), (640, 360), (480, 480), (400, 640))
KINDS = (
    "plane",
    "corner",
    "cylinder-concave",
    "cylinder-convex",
    "sphere-concave",
    "sphere-convex",
    "bowl",
    "cylinder-floor",
    "cone-wall",
    "bumps",
    "waves",
)
MODES = ("standard", "conformal", "content", "content-paper")
# the frame's half extent at unit depth (default projector: f = 1.4 * width)
HALF_X, HALF_Y = 0.5 / 1.4, 0.5 * 800 / 1280 / 1.4


def axis_angle(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation matrix (3, 3) of the rotation vector ``r`` (3,)."""
    out: NDArray[np.float64] = rodrigues(np.asarray(r, float)[None])[0]
    return out


@dataclass(frozen=True)
class Turned:
    """An analytic surface turned by the rotation ``rot`` about the projector's centre
    (a tilted cylinder axis, a cone wall seen rolled): ``X -> rot X``."""

    inner: Any
    rot: tuple[tuple[float, float, float], ...]

    @property
    def name(self) -> str:
        """The inner surface's name."""
        return str(self.inner.name)

    @property
    def developable(self) -> bool:
        """As the inner surface."""
        return bool(self.inner.developable)

    @property
    def grid_smooth(self) -> bool:
        """As the inner surface."""
        return bool(self.inner.grid_smooth)

    def intersect(self, origins: NDArray[np.float64], dirs: NDArray[np.float64]) -> Any:
        """Hits of the rays turned back into the inner surface's frame."""
        r = np.asarray(self.rot)
        return self.inner.intersect(origins @ r, dirs @ r)

    def patch(self, points: NDArray[np.float64]) -> Any:
        """The inner surface's patches."""
        return self.inner.patch(points @ np.asarray(self.rot))


def _rot(axis: NDArray[np.float64], deg: float) -> tuple[tuple[float, float, float], ...]:
    m = axis_angle(np.asarray(axis, float) / np.linalg.norm(axis) * np.deg2rad(deg))
    return tuple(tuple(float(x) for x in row) for row in m)  # type: ignore[return-value]


def _plane_axis(rng: np.random.Generator) -> NDArray[np.float64]:
    a = rng.uniform(0, 2 * np.pi)
    return np.array([np.cos(a), np.sin(a), 0.0])


def draw_surface(kind: str, rng: np.random.Generator, cell: float) -> tuple[Any, dict[str, Any]]:
    """A random member of the class ``kind`` and its parameters; ``cell`` is the grid's
    cell width at unit depth (for the corrugations' wavelength)."""
    u = rng.uniform
    p: dict[str, Any] = {}
    s: Any
    if kind == "plane":
        tilt, dist = u(0, 60), u(0.8, 3.0)
        axis = _plane_axis(rng)
        n = axis_angle(axis * np.deg2rad(tilt)) @ np.array([0.0, 0.0, -1.0])
        s = Plane("plane", tuple(n), float(n @ np.array([0.0, 0.0, dist])))
        p = {"tilt": tilt, "dist": dist}
    elif kind == "corner":
        z0 = u(0.8, 3.0)
        s = Corner(
            "corner",
            x0=u(-0.25, 0.25) * z0,
            z0=z0,
            half_angle=np.deg2rad(u(30, 60)),
            concave=bool(rng.integers(2)),
        )
        tilt = u(0, 20)
        s = Turned(s, _rot(_plane_axis(rng), tilt))
        p = {"z0": z0, "tilt": tilt}
    elif kind == "cylinder-concave":
        r = u(0.7, 3.0)
        far = u(0.8, min(3.0, 2 * r - 0.3))  # the wall straight ahead, inside the cylinder
        cx = u(-0.3, 0.3) * r
        cz = far - np.sqrt(r * r - cx * cx)
        tilt = u(0, 30)
        s = Turned(Cylinder("cylinder-concave", cx, cz, r, True), _rot(_plane_axis(rng), tilt))
        p = {"r": r, "far": far, "tilt": tilt}
    elif kind == "cylinder-convex":
        r = u(0.15, 1.5)
        near = u(0.8, 3.0)
        cx = u(-0.3, 0.3) * near * HALF_X
        s = Turned(
            Cylinder("cylinder-convex", cx, near + r, r, False), _rot(_plane_axis(rng), u(0, 30))
        )
        p = {"r": r, "near": near}
    elif kind == "sphere-concave":
        r = u(0.8, 3.0)
        far = u(0.8, min(3.0, 2 * r - 0.3))
        c = np.array([u(-0.2, 0.2) * r, u(-0.2, 0.2) * r, 0.0])
        c[2] = far - np.sqrt(r * r - c[0] ** 2 - c[1] ** 2)
        s = Sphere("sphere-concave", tuple(c), r, True)
        p = {"r": r, "far": far}
    elif kind == "sphere-convex":
        r = u(0.2, 1.5)
        near = u(0.8, 3.0)
        c = (u(-0.3, 0.3) * near * HALF_X, u(-0.3, 0.3) * near * HALF_Y, near + r)
        s = Sphere("sphere-convex", c, r, False)
        p = {"r": r, "near": near}
    elif kind == "bowl":
        z0 = u(0.8, 3.0)
        k = float(np.exp(u(np.log(0.05), np.log(1.5))))
        s = Bowl("bowl", z0, k)
        p = {"z0": z0, "k": k}
    elif kind == "cylinder-floor":
        r = u(0.4, 1.4)
        far = u(1.0, 3.0)
        floor = u(0.3, 0.9) * (far - r) * HALF_Y + u(0.0, 0.4) * r * HALF_Y
        s = CylinderFloor("cylinder-floor", u(-0.2, 0.2) * r, far - r, r, max(floor, 0.08))
        p = {"r": r, "far": far, "floor": floor}
    elif kind == "cone-wall":
        z0 = u(0.8, 3.0)
        s = ConeWall(
            "cone-wall",
            x0=u(-0.3, 0.3) * z0 * HALF_X,
            z0=z0,
            apex_y=-u(0.8, 2.5) * z0,
            alpha=u(0.05, 0.5),
            turn=u(0.1, 0.7),
        )
        s = Turned(s, _rot(np.array([0.0, 0.0, 1.0]), u(-20, 20)))
        p = {"z0": z0}
    elif kind == "bumps":
        z0 = u(0.8, 3.0)
        half = z0 * HALF_X
        bumps = []
        for _ in range(int(rng.integers(1, 13))):
            sigma = float(np.exp(u(np.log(0.1 * cell * z0), np.log(0.06 * z0))))
            slope = u(0.05, 0.35)  # largest slope ~ 0.6 height / sigma
            h = slope * sigma / 0.6 * (1 if rng.integers(2) else -1)
            bumps.append((u(-1, 1) * half, u(-1, 1) * half * 0.625, sigma, h))
        s = Bumps("bumps", z0, tuple(bumps), yaw=u(-0.5, 0.5))
        p = {"z0": z0, "n": len(bumps), "min_sigma_cells": min(b[2] for b in bumps) / (cell * z0)}
    elif kind == "waves":
        z0 = u(0.8, 3.0)
        cells = float(np.exp(u(np.log(0.8), np.log(10.0))))
        wavelength = cells * cell * z0
        slope = u(0.05, 0.5)
        s = Waves(
            "waves",
            z0,
            wavelength=wavelength,
            amplitude=slope * wavelength / (2 * np.pi),
            direction=u(0, np.pi),
            yaw=u(-0.5, 0.5),
        )
        p = {"z0": z0, "cells": cells, "slope": slope}
    else:
        raise ValueError(kind)
    return s, p


def draw_mask(rng: np.random.Generator, size: tuple[int, int]) -> NDArray[np.float32]:
    """One to three elliptic blobs, together at most half the image."""
    w, h = size
    yy, xx = np.mgrid[0:h, 0:w]
    n = int(rng.integers(1, 4))
    total = rng.uniform(0.01, 0.5)
    m = np.zeros((h, w), bool)
    for share in rng.dirichlet(np.ones(n)) * total:
        aspect = rng.uniform(0.4, 2.5)
        area = share * w * h / np.pi  # rx * ry
        rx, ry = np.sqrt(area * aspect), np.sqrt(area / aspect)
        cx, cy = rng.uniform(0.1, 0.9) * w, rng.uniform(0.1, 0.9) * h
        m |= ((xx - cx) / rx) ** 2 + ((yy - cy) / ry) ** 2 <= 1
    return m.astype(np.float32)


@dataclass
class Case:
    """One drawn case."""

    index: int
    kind: str
    surface: Any
    params: dict[str, Any]
    mode: str
    grid: Grid
    adaptive: bool
    content: tuple[int, int]
    mask: NDArray[np.float32] | None

    def describe(self) -> str:
        """One line: what was drawn."""
        par = " ".join(f"{k}={v:.3g}" for k, v in self.params.items())
        mask = "-" if self.mask is None else f"{self.mask.mean():.2f}"
        return (
            f"{self.kind:16s} {self.mode:13s} {self.grid!s:6s} "
            f"{'adapt' if self.adaptive else 'plain'} {self.content[0]}x{self.content[1]} "
            f"mask {mask:4s} {par}"
        )


def draw_case(seed: int, index: int) -> Case:
    """Case ``index`` of ``seed`` (reproducible alone)."""
    rng = np.random.default_rng([seed, index])
    kind = KINDS[int(rng.integers(len(KINDS)))]
    cols = int(rng.integers(10, 41))
    rows = cols if rng.random() < 0.5 else int(rng.integers(10, 41))
    grid = Grid(cols, rows)
    surface, params = draw_surface(kind, rng, 2 * HALF_X / cols)
    mode = MODES[int(rng.integers(len(MODES)))]
    content = CONTENT_SIZES[int(rng.integers(len(CONTENT_SIZES)))]
    adaptive = bool(rng.random() < 0.75)
    mask = draw_mask(rng, content) if mode.startswith("content") and rng.random() < 0.85 else None
    return Case(index, kind, surface, params, mode, grid, adaptive, content, mask)


def exactness(case: Case) -> float | None:
    """The angle error / size std a developable surface must reach, None where no such
    line applies.

    Smooth at the grid's scale: the class is developable with no crease but a straight
    one (``grid_smooth``; planes, corners, cylinders, cone walls: exact, 3e-4), or
    corrugations at least 2 grid cells long across the waves (on the frame at the wall's
    depth) with the adaptive grid on (the one that follows them: 0.005). Finer waves,
    or waves with the adaptive grid off, are detail the grid cannot follow: no line.
    A curved developable one is smooth at the grid's scale where every cell edge's bend
    (:func:`grid_bend`) is at most :data:`BEND_EXACT`, or that times the most the
    adaptive grid may split a cell when it is on.
    """
    s = case.surface
    if not s.developable:
        return None
    if s.grid_smooth:
        limit = BEND_EXACT * (_split_factor(case) if case.adaptive else 1.0)
        return EXACT if grid_bend(case) <= limit else None
    if case.kind == "waves" and case.adaptive and case.params["cells"] >= 2.0:
        return EXACT_FINE
    return None


def _split_factor(case: Case) -> float:
    """How many times the adaptive grid may split a cell (``warp/adaptive.py``: at most
    8x, lines at least 4 px apart), the least of the two directions."""
    px = min(1279 / case.grid.cols, 799 / case.grid.rows)
    return float(min(8.0, np.floor(px / 4.0)))


def grid_bend(case: Case) -> float:
    """The largest bend ``kappa h`` of the grid's cell edges on the analytic surface:
    the sagitta ``s`` of the surface point under the edge's middle pixel off the chord
    between its ends, ``kappa h ~ 8 s / h``; edges across a crease (their unfolding is
    exact) and off the surface are left out."""
    proj = Projector.default()
    uv = case.grid.vertices(proj)
    worst = 0.0
    for a, b in ((uv[:, :-1], uv[:, 1:]), (uv[:-1, :], uv[1:, :])):
        p0 = surface_points(case.surface, proj.K, a)
        p1 = surface_points(case.surface, proj.K, b)
        pm = surface_points(case.surface, proj.K, 0.5 * (a + b))
        chord = p1 - p0
        h = np.linalg.norm(chord, axis=-1)
        off = pm - p0
        along = np.sum(off * chord, axis=-1) / np.maximum(h, 1e-12)
        sag = np.sqrt(np.maximum(np.sum(off * off, axis=-1) - along**2, 0.0))
        bend = 8.0 * sag / np.maximum(h, 1e-12)
        same = case.surface.patch(np.nan_to_num(p0)) == case.surface.patch(np.nan_to_num(p1))
        ok = same & np.isfinite(bend) & np.isfinite(p0).all(-1) & np.isfinite(p1).all(-1)
        if ok.any():
            worst = max(worst, float(bend[ok].max()))
    return worst


@dataclass
class Outcome:
    """What one case showed."""

    failures: list[str]
    figures: dict[str, float]
    seconds: float


def _warp(case: Case, mode: str, alternation: str, mask: NDArray[np.float32] | None) -> Any:
    sim = simulate_surface(case.surface)
    settings = WarpSettings(
        mode=mode,  # type: ignore[arg-type]
        alternation=alternation,  # type: ignore[arg-type]
        grid=case.grid,
        adaptive=case.adaptive,
    )
    warp = compute_warp(sim, case.content, mask, settings)
    m = shown_map(warp, None if mode == "standard" else sim)
    return sim, warp, m


def _display_checks(
    case: Case, warp: Any, m: NDArray[np.float32], d: Distortion, tag: str
) -> tuple[list[str], dict[str, float]]:
    fails = []
    cover = visible_fraction(m, case.content)
    nan_on_surface = 0
    if warp.depth is not None:
        nan_on_surface = int(np.sum(~np.isfinite(warp.image_xy[np.isfinite(warp.depth)])))
    if np.isinf(m).any() or np.isinf(warp.image_xy).any() or nan_on_surface:
        fails.append(f"nonfinite{tag}")
    if d.folds:
        fails.append(f"fold{tag}({d.folds})")
    if cover < COVER:
        fails.append(f"cover{tag}({cover:.5f})")
    return fails, {f"cover{tag}": cover, f"folds{tag}": d.folds}


def run_case(case: Case) -> Outcome:
    """Warp and score ``case``; the failed lines (empty: all met)."""
    t0 = time.perf_counter()
    mode, alternation = (
        ("content", "paper") if case.mode == "content-paper" else (case.mode, "ours")
    )
    try:
        sim, warp, m = _warp(case, mode, alternation, case.mask)
    except (WarpError, InputError) as e:
        return Outcome([f"warperror({e})"], {}, time.perf_counter() - t0)
    except Exception:
        return Outcome([f"crash({traceback.format_exc(limit=-3)!r})"], {}, time.perf_counter() - t0)
    d = measure(m, case.surface, sim.projector.K)
    fails, fig = _display_checks(case, warp, m, d, "")
    fig.update(angle=d.angle_mean, size=d.size_std)
    fig["choice"] = warp.meta.get("guard", {}).get("choice", "-")
    if case.surface.developable:
        fig["bend"] = grid_bend(case)
    exact = exactness(case) if mode != "standard" else None
    if exact is not None and (d.angle_mean > exact or d.size_std > exact):
        fails.append(f"exact({d.angle_mean:.2e},{d.size_std:.2e}>{exact:g})")
    if (
        mode == "content"
        and case.mask is not None
        and not case.surface.developable
        and (in_mask(d, case.mask).sum() > 0)
    ):
        try:
            _, cwarp, cm = _warp(case, "conformal", "ours", None)
        except (WarpError, InputError) as e:
            fails.append(f"conformal-warperror({e})")
            return Outcome(fails, fig, time.perf_counter() - t0)
        cd = measure(cm, case.surface, sim.projector.K)
        more, cfig = _display_checks(case, cwarp, cm, cd, "-conformal")
        fails += more
        fig.update(cfig)
        a = cd.select(in_mask(cd, case.mask))
        b = d.select(in_mask(d, case.mask))
        if len(a.angle) and len(b.angle):
            ra = b.angle_mean / max(a.angle_mean, 1e-12)
            rs = b.size_std / max(a.size_std, 1e-12)
            fig.update(angle_x=ra, size_x=rs)
            if alternation == "ours" and (ra > 1.0 or rs > 1.0):
                fails.append(f"worse(angle {ra:.3f}x, size {rs:.3f}x)")
    return Outcome(fails, fig, time.perf_counter() - t0)
