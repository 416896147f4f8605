"""compute_warp: the whole method, from a Surface and a content map to a Warp.

Modes
-----
``standard``
    No pre-warp: the content is fitted (letterboxed) to the projector frame, as a plain
    projector shows it.
``conformal``
    E_a only with uniform weights: the iLamps-style baseline.
``content`` (default)
    The content-free warp E' = E_a + lambda E_r (paper §4.1), then the content-aware
    refinement (:class:`~adaproj_edge.warp.solve.ContentAwareSolver`) when the content
    map marks some of the content as salient.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD, ContentMap
from adaproj_edge.errors import InputError, WarpError
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.adaptive import refine_grid
from adaproj_edge.warp.anderson import Anderson
from adaproj_edge.warp.guard import guard
from adaproj_edge.warp.mesh import MeshGeometry, WarpCache, keeps_orientation
from adaproj_edge.warp.placement import DEFAULT_UP, Placement, place
from adaproj_edge.warp.solve import (
    ContentAwareSolver,
    ContentAwareWeights,
    PaperAlternation,
    solve_conformal,
    solve_content_free,
)
from adaproj_edge.warp.warpmap import Grid, Warp


class StepSolver(Protocol):
    def step(self, v: FloatArray, w: FloatArray) -> FloatArray: ...


PaperWarp = Callable[
    [Surface, tuple[int, int], ContentMap | None, "WarpSettings"],
    tuple[FloatArray, dict[str, Any]],
]


@dataclass(frozen=True)
class Backend:
    """The three solves; :data:`FAST` is the product, the reference backend in
    :mod:`adaproj_edge.warp.reference` the yardstick. ``paper``, when given, computes
    the whole ``alternation="paper"`` warp its own way (the paper as written,
    straightforwardly: content pixel coordinates (R*C, 2) of the vertices and meta)."""

    conformal: Callable[[MeshGeometry], FloatArray]
    content_free: Callable[[MeshGeometry, FloatArray, float], tuple[FloatArray, FloatArray]]
    content_aware: Callable[[MeshGeometry, ContentAwareWeights], StepSolver]
    paper: PaperWarp | None = None


FAST = Backend(solve_conformal, solve_content_free, ContentAwareSolver)

Mode = Literal["content", "conformal", "standard"]
MODES: tuple[Mode, ...] = ("content", "conformal", "standard")
Alternation = Literal["ours", "paper"]
ALTERNATIONS: tuple[Alternation, ...] = ("ours", "paper")


@dataclass(frozen=True)
class WarpSettings:
    """Everything that decides a warp besides the surface and the content.

    mode : "content" | "conformal" | "standard"
    grid : mesh resolution (cells)
    threshold : T of eq. 5 (content map >= T is salient)
    lam : lambda of eq. 1 for the content-free warp E'
    max_iterations, tolerance : alternation stops when the mean vertex motion is below
        ``tolerance`` content pixels or after ``max_iterations`` steps
    up : "up" in frame P (from the IMU; default: the projector held level)
    weights : the content-aware energy's weights
    alternation : "ours" (default) or "paper" (§4.2 as written: fixed boundary,
        regulariser toward the last iterate; kept for comparison)
    adaptive : split the grid's columns and rows where the surface bends faster than
        the grid samples it (:mod:`~adaproj_edge.warp.adaptive`); the warp's grid is
        then finer there
    """

    mode: Mode = "content"
    grid: Grid = field(default_factory=Grid)
    threshold: float = DEFAULT_THRESHOLD
    lam: float = 1.0
    max_iterations: int = 10
    tolerance: float = 0.05
    up: tuple[float, float, float] = DEFAULT_UP
    weights: ContentAwareWeights = field(default_factory=ContentAwareWeights)
    alternation: Alternation = "ours"
    adaptive: bool = True

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise InputError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if self.alternation not in ALTERNATIONS:
            raise InputError(f"alternation must be one of {', '.join(ALTERNATIONS)}")
        if not 0.0 <= self.threshold <= 1.0:
            raise InputError(f"threshold must be in [0, 1], got {self.threshold}")
        if self.max_iterations < 0 or self.tolerance <= 0 or self.lam < 0:
            raise InputError("max_iterations, tolerance and lambda must be positive")


def standard_warp(surface: Surface, content_size: tuple[int, int], grid: Grid) -> Warp:
    """The content letterboxed into the full frame: what a plain projector shows."""
    proj = surface.projector
    grid_uv = grid.vertices(proj)
    w, h = content_size
    scale = min(proj.width / w, proj.height / h)
    ox = (proj.width - scale * w) / 2.0
    oy = (proj.height - scale * h) / 2.0
    image_xy = (grid_uv + 0.5 - np.array([ox, oy])) / scale - 0.5
    meta: dict[str, Any] = {"mode": "standard", "grid": str(grid), "iterations": 0}
    return Warp(grid_uv, image_xy, content_size, proj, meta, depth=None)


def compute_warp(
    surface: Surface,
    content_size: tuple[int, int],
    content_map: ContentMap | NDArray[np.floating] | None = None,
    settings: WarpSettings | None = None,
    backend: Backend = FAST,
    cache: WarpCache | None = None,
) -> Warp:
    """The warp for ``surface`` and content of ``content_size`` (w, h) pixels.

    Parameters
    ----------
    surface : Surface
        Projector-space point map (any lattice resolution).
    content_size : (w, h)
    content_map : ContentMap or (h', w') float array in [0, 1], optional
        The content map C (saliency max user mask) over the whole content, at any
        resolution; None means uniform. Vertices are salient where C >= threshold.
    settings : WarpSettings, optional
    backend : the solves (the fast ones, or the reference for comparison)
    cache : WarpCache, optional
        Keeps the mesh topology and solver structures between calls (a device keeps
        one; a scene seen again skips that set-up).

    Returns
    -------
    Warp with ``meta`` holding the mode, grid, iterations and stage timings (s).
    """
    settings = settings or WarpSettings()
    w, h = content_size
    if w < 2 or h < 2:
        raise InputError(f"content size {w}x{h} is too small")
    if settings.mode == "standard":
        return standard_warp(surface, content_size, settings.grid)
    surface.check_usable()
    if settings.mode == "content" and settings.alternation == "paper" and backend.paper:
        return _paper_warp(surface, content_size, content_map, settings, backend.paper)
    timings: dict[str, Any] = {}
    t0 = time.perf_counter()
    mesh = MeshGeometry.build(surface, settings.grid, cache)
    extra: dict[str, Any] = {}
    if settings.adaptive:
        refinement = refine_grid(surface, settings.grid, mesh.curved_cells)
        if refinement.refined:
            mesh = MeshGeometry.build(surface, refinement.grid, cache, refinement.grid_uv)
            extra["mesh"] = str(refinement.grid)
            extra["refined"] = {
                "columns": refinement.factor_x.tolist(),
                "rows": refinement.factor_y.tolist(),
            }
    v = backend.conformal(mesh)
    timings["conformal"] = time.perf_counter() - t0
    iterations = 0
    salient_fraction = 0.0
    if settings.mode == "content":
        cmap = _content_map(content_map, content_size, settings.threshold)
        v, placement, iterations, salient_fraction, guarded = content_aware(
            mesh, v, content_size, cmap, settings, backend, timings
        )
        extra.update(guarded)
        timings["refine"] = time.perf_counter() - t0 - timings["init"]
    else:
        placement = place(mesh, v, content_size, settings.up)
    timings["total"] = time.perf_counter() - t0
    warp = make_warp(
        mesh, v, placement, surface, content_size, settings, iterations, salient_fraction, timings
    )
    warp.meta.update(extra)
    return warp


def content_aware(
    mesh: MeshGeometry,
    v_conformal: FloatArray,
    content_size: tuple[int, int],
    content_map: ContentMap | None,
    settings: WarpSettings,
    backend: Backend = FAST,
    timings: dict[str, Any] | None = None,
) -> tuple[FloatArray, Placement, int, float, dict[str, Any]]:
    """The ``content`` mode from the conformal positions ``v_conformal`` (n, 2).

    With salient and non-salient content in view, our alternation (:func:`refine`)
    starts from the conformal warp (its fixed point does not depend on the start) and
    :func:`~adaproj_edge.warp.guard.guard` keeps it only where it is no worse than the
    conformal warp on the subject; with none (or no content map), the content-free warp
    E' = E_a + lambda E_r (paper §4.1). ``alternation="paper"``: E', then the paper's
    alternation as written.

    Returns positions (n, 2), their placement, the alternation's steps, the salient
    vertex fraction and meta (``guard``: what was kept and why).
    """
    t0 = time.perf_counter()
    timings = {} if timings is None else timings
    placement = place(mesh, v_conformal, content_size, settings.up)
    w = None if content_map is None else content_map.weights(placement.apply(v_conformal))
    if content_map is None or w is None or settings.alternation == "paper" or w.min() == w.max():
        v, _ = backend.content_free(mesh, v_conformal, settings.lam)
        placement = place(mesh, v, content_size, settings.up)
        timings["init"] = time.perf_counter() - t0
        if content_map is None or settings.alternation != "paper":
            return v, placement, 0, 0.0 if w is None else float(w.mean()), {}
        v, iterations, fraction = refine_as_paper(
            mesh, v_conformal, v, placement, content_map, settings
        )
        return v, placement, iterations, fraction, {}
    timings["init"] = time.perf_counter() - t0
    # the conformal warp's scale is set by two pinned vertices; the salient region's is
    # that of the surface: start there (on a developable surface that is the answer)
    e = mesh.edges
    salient = (w[e[:, 0]] + w[e[:, 1]]) > 0
    chord = np.linalg.norm(v_conformal[e[salient, 0]] - v_conformal[e[salient, 1]], axis=1)
    scale = float(np.sum(mesh.lengths[salient]) / np.sum(chord))
    start = Placement(placement.angle, placement.scale / scale, placement.offset, placement.centre)
    v, aware_placement, iterations, fraction = refine(
        mesh, v_conformal * scale, start, content_map, settings, backend, timings
    )
    choice = guard(mesh, (v, aware_placement), (v_conformal, placement), content_map, settings.up)
    return choice.v, choice.placement, iterations, fraction, {"guard": choice.meta}


def _content_map(
    content_map: ContentMap | NDArray[np.floating] | None,
    content_size: tuple[int, int],
    threshold: float,
) -> ContentMap | None:
    if content_map is None:
        return None
    values = content_map.values if isinstance(content_map, ContentMap) else content_map
    if np.ndim(values) != 2:
        raise InputError(f"content map must be a 2D array, got shape {np.shape(values)}")
    return ContentMap(np.asarray(values, np.float32), content_size, threshold)


def _paper_warp(
    surface: Surface,
    content_size: tuple[int, int],
    content_map: ContentMap | NDArray[np.floating] | None,
    settings: WarpSettings,
    paper: PaperWarp,
) -> Warp:
    cmap = _content_map(content_map, content_size, settings.threshold)
    image_xy, meta = paper(surface, content_size, cmap, settings)
    grid_uv = settings.grid.vertices(surface.projector)
    rows, cols = grid_uv.shape[:2]
    return Warp(
        grid_uv,
        image_xy.reshape(rows, cols, 2),
        content_size,
        surface.projector,
        {"mode": "content", "alternation": "paper", "grid": str(settings.grid), **meta},
    )


def refine(
    mesh: MeshGeometry,
    v: FloatArray,
    placement: Placement,
    content_map: ContentMap,
    settings: WarpSettings,
    backend: Backend = FAST,
    timings: dict[str, Any] | None = None,
) -> tuple[FloatArray, Placement, int, float]:
    """The content-aware alternation (Algorithm 1, our energy); returns the final
    positions, their placement, the number of steps and the salient vertex fraction.

    Rounds: the salient set (eq. 8, from the current placement) and the placement held,
    steps (Anderson-accelerated, :mod:`~adaproj_edge.warp.anderson`) until the mean
    vertex motion is below the tolerance (ten times it while the salient set may still
    change); then the content is placed again, and when that shows new salient
    vertices another round follows. The salient set only grows (a vertex that showed
    salient content stays salient), so the alternation cannot oscillate.
    """
    solver: StepSolver | None = None
    iterations = 0
    steps: list[float] = []
    accel = Anderson()
    # eq. 8 at the start of every round, from the placement of that moment
    w = content_map.weights(placement.apply(v)).astype(np.float64)
    placed = True  # the placement is that of v
    while iterations < settings.max_iterations and w.min() != w.max():
        t0 = time.perf_counter()
        if solver is None:
            solver = backend.content_aware(mesh, settings.weights)
        g = solver.step(v, w)
        v_next = accel.next(v.ravel(), g.ravel()).reshape(-1, 2)
        if not _orientation_ok(mesh, v_next):
            accel.reset()
            v_next = g  # the plain step, unless it folds too
            if not _orientation_ok(mesh, v_next):
                break  # keep the last fold-free iterate
        # the plain step's length: how far the iterate still is from the fixed point
        motion = placement.scale * float(np.mean(np.linalg.norm(g - v, axis=1)))
        v, placed = v_next, False
        iterations += 1
        steps.append(time.perf_counter() - t0)
        if motion < settings.tolerance:
            # the round has settled: place the content again and look at it
            placement = place(mesh, v, content_map.content_size, settings.up, placement)
            placed = True
            grown = np.maximum(w, content_map.weights(placement.apply(v)))
            if np.array_equal(grown, w):
                break
            w = grown
            accel.reset()  # a new salient set: a new fixed-point map
    if not placed:
        placement = place(mesh, v, content_map.content_size, settings.up, placement)
    if timings is not None:
        timings["iterations"] = steps
    return v, placement, iterations, float(w.mean())


def refine_as_paper(
    mesh: MeshGeometry,
    v_conformal: FloatArray,
    v: FloatArray,
    placement: Placement,
    content_map: ContentMap,
    settings: WarpSettings,
) -> tuple[FloatArray, int, float]:
    """Algorithm 1 with eq. 9 as written (boundary fixed, so the placement stays)."""
    paper = PaperAlternation(mesh, v_conformal, v, settings.lam)
    iterations = 0
    fraction = 0.0
    for _ in range(settings.max_iterations):
        xy = placement.apply(v)
        c = content_map.sample(xy).astype(np.float64)
        w = (c >= settings.threshold).astype(np.float64)
        fraction = float(w.mean())
        if w.min() == w.max():
            break
        v_new = paper.step(v, w, c)
        if not _orientation_ok(mesh, v_new):
            break
        motion = float(np.mean(np.linalg.norm(placement.apply(v_new) - xy, axis=1)))
        v = v_new
        iterations += 1
        if motion < settings.tolerance:
            break
    return v, iterations, fraction


def _orientation_ok(mesh: MeshGeometry, v: FloatArray) -> bool:
    """No triangle folded over (all keep the orientation they have in the projector)."""
    return keeps_orientation(mesh, v)


def make_warp(
    mesh: MeshGeometry,
    v: FloatArray,
    placement: Placement,
    surface: Surface,
    content_size: tuple[int, int],
    settings: WarpSettings,
    iterations: int,
    salient_fraction: float,
    timings: dict[str, Any],
) -> Warp:
    """A Warp from solved positions ``v`` (n, 2) of ``mesh`` and their placement; raises
    :class:`WarpError` if the mesh folds over. For callers that run the solves
    themselves (the device runtime keeps solver state between updates)."""
    if not _orientation_ok(mesh, v):
        raise WarpError("the warp folds over; the surface is too irregular for this grid")
    rows, cols = mesh.grid.rows + 1, mesh.grid.cols + 1
    image_xy = np.full((rows * cols, 2), np.nan)
    image_xy[mesh.verts] = placement.apply(v)
    depth = mesh.points[:, 2].copy()
    depth[~mesh.used] = np.nan
    meta: dict[str, Any] = {
        "mode": settings.mode,
        "alternation": settings.alternation,
        "grid": str(settings.grid),
        "iterations": iterations,
        "threshold": settings.threshold,
        "salient_vertex_fraction": salient_fraction,
        "used_vertices": mesh.n,
        "timings": timings,
        "surface": surface.meta,
    }
    return Warp(
        mesh.grid_uv,
        image_xy.reshape(rows, cols, 2),
        content_size,
        surface.projector,
        meta,
        depth=depth.reshape(rows, cols),
    )
