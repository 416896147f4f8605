"""The steps of the method and their settings: standard (letterbox), the content-aware
alternation (ours, and the paper's as written), and a Warp from solved positions.
:mod:`adaproj_edge.warp.planner` puts them together (:func:`compute_warp`).

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

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD, ContentMap
from adaproj_edge.errors import InputError, WarpError
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.anderson import Anderson
from adaproj_edge.warp.guard import guard
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.orientation import unfolded
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
    """A content-aware solver: one solve at a time from the previous iterate."""

    def step(self, v: FloatArray, w: FloatArray) -> FloatArray:
        """One solve with saliency ``w`` (n,) in {0, 1} from the iterate ``v`` (n, 2)."""
        ...


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
FOLDS = "the warp folds over; the surface is too irregular for this grid"


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
        the grid samples it (:mod:`~adaproj_edge.warp.adaptive`; the full-grid path);
        the warp's grid is then finer there
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


def standard_warp(projector: Projector, content_size: tuple[int, int], grid: Grid) -> Warp:
    """The content letterboxed into the full frame: what a plain projector shows."""
    proj = projector
    grid_uv = grid.vertices(proj)
    w, h = content_size
    scale = min(proj.width / w, proj.height / h)
    ox = (proj.width - scale * w) / 2.0
    oy = (proj.height - scale * h) / 2.0
    image_xy = (grid_uv + 0.5 - np.array([ox, oy])) / scale - 0.5
    meta: dict[str, Any] = {"mode": "standard", "grid": str(grid), "iterations": 0}
    return Warp(grid_uv, image_xy, content_size, proj, meta, depth=None)


def content_aware(
    mesh: MeshGeometry,
    v_conformal: FloatArray,
    placement: Placement,
    content_map: ContentMap,
    settings: WarpSettings,
    backend: Backend = FAST,
    on_step: Callable[[], None] | None = None,
    surface: Surface | None = None,
) -> tuple[FloatArray, Placement, int, float, dict[str, Any]] | None:
    """Our ``content`` mode from the conformal positions ``v_conformal`` (n, 2) placed
    by ``placement``; None when nothing or everything salient shows (then the
    content-free warp E' is the answer).

    What shows is read through ``placement``, which says nothing where the conformal
    warp folds over (the rectangle inscribed in a flattening that overlaps itself may
    hold one vertex, salient or not by chance): there "nothing salient shows" is not a
    verdict, and the step fails on the fold (raises :class:`WarpError`) as the
    alternation from that start would.

    The alternation (:func:`refine`) starts from the conformal warp scaled to the
    salient region's size on the surface (its fixed point does not depend on the start;
    on a developable surface that start is the answer), and
    :func:`~adaproj_edge.warp.guard.guard` keeps its result only where it is no worse
    than the conformal warp on the subject (as displayed, given the ``surface`` the mesh
    was built from).

    Returns
    -------
    Positions (n, 2), their placement, the steps taken, the salient vertex fraction and
    meta (``guard``: what was kept and why).
    """
    w = content_map.weights(placement.apply(v_conformal))
    if w.min() == w.max():
        if not unfolded(v_conformal, mesh.tris):
            raise WarpError(FOLDS)
        return None
    e = mesh.edges
    salient = (w[e[:, 0]] + w[e[:, 1]]) > 0
    ends = np.take(v_conformal, e[salient].T, axis=0)  # (2, E', 2)
    chord = np.linalg.norm(ends[0] - ends[1], axis=1)
    scale = float(np.sum(mesh.lengths[salient]) / np.sum(chord))
    start = placement.for_scaled(scale)
    v, aware_placement, iterations, fraction = refine(
        mesh, v_conformal * scale, start, content_map, settings, backend, on_step
    )
    choice = guard(
        mesh,
        (v, aware_placement),
        (v_conformal, placement),
        content_map,
        settings.up,
        surface=surface,
        flatten=True,
    )
    return choice.v, choice.placement, iterations, fraction, {"guard": choice.meta}


def refine(
    mesh: MeshGeometry,
    v: FloatArray,
    placement: Placement,
    content_map: ContentMap,
    settings: WarpSettings,
    backend: Backend = FAST,
    on_step: Callable[[], None] | None = None,
) -> tuple[FloatArray, Placement, int, float]:
    """The content-aware alternation (Algorithm 1, our energy); returns the final
    positions, their placement, the number of steps and the salient vertex fraction.
    ``on_step`` is called after each step taken (a caller's stopwatch).

    Rounds: the salient set (eq. 8, from the current placement) and the placement held,
    steps (Anderson-accelerated, :mod:`~adaproj_edge.warp.anderson`) until the plain
    step moves the vertices less than the tolerance (mean, content pixels); then the
    content is placed again, and when that shows new salient vertices another round
    follows. The salient set only grows (a vertex that showed salient content stays
    salient), so the alternation cannot oscillate.
    """
    solver: StepSolver | None = None
    iterations = 0
    accel = Anderson()
    # eq. 8 at the start of every round, from the placement of that moment
    w = content_map.weights(placement.apply(v)).astype(np.float64)
    placed = True  # the placement is that of v
    while iterations < settings.max_iterations and w.min() != w.max():
        if solver is None:
            solver = backend.content_aware(mesh, settings.weights)
        g = solver.step(v, w)
        v_next = accel.next(v.ravel(), g.ravel()).reshape(-1, 2)
        if not unfolded(v_next, mesh.tris):
            accel.reset()
            v_next = g  # the plain step, unless it folds too
            if not unfolded(v_next, mesh.tris):
                break  # keep the last fold-free iterate
        # the plain step's length: how far the iterate still is from the fixed point
        d = g - v
        motion = placement.scale * float(np.mean(np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])))
        v, placed = v_next, False
        iterations += 1
        if on_step is not None:
            on_step()
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
        if not unfolded(v_new, mesh.tris):
            break
        motion = float(np.mean(np.linalg.norm(placement.apply(v_new) - xy, axis=1)))
        v = v_new
        iterations += 1
        if motion < settings.tolerance:
            break
    return v, iterations, fraction


def make_warp(
    mesh: MeshGeometry,
    v: FloatArray,
    placement: Placement,
    surface: Surface,
    content_size: tuple[int, int],
    settings: WarpSettings,
    iterations: int,
    salient_fraction: float,
) -> Warp:
    """A Warp from solved positions ``v`` (n, 2) of ``mesh`` and their placement; raises
    :class:`WarpError` if the mesh folds over. For callers that run the solves
    themselves (the device runtime keeps solver state between updates)."""
    if not unfolded(v, mesh.tris):
        raise WarpError(FOLDS)
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


def paper_result(
    surface: Surface,
    content_size: tuple[int, int],
    content_map: ContentMap,
    settings: WarpSettings,
    paper: PaperWarp,
) -> Warp:
    """The whole ``alternation="paper"`` warp made by a backend's own ``paper``."""
    image_xy, meta = paper(surface, content_size, content_map, settings)
    grid_uv = settings.grid.vertices(surface.projector)
    rows, cols = grid_uv.shape[:2]
    return Warp(
        grid_uv,
        image_xy.reshape(rows, cols, 2),
        content_size,
        surface.projector,
        {"mode": "content", "alternation": "paper", "grid": str(settings.grid), **meta},
    )
