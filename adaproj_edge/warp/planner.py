"""The warp method, one path for every caller: surface + content map -> Warp.

:class:`WarpPlanner` makes a warp in two steps that a device runs at different times:

1. :meth:`~WarpPlanner.content_free`: the conformal solve, E' = E_a + lambda E_r
   (paper eq. 7) and the content's placement, on the full grid. It depends on the
   surface alone, so a device caches it per pose (:mod:`adaproj_edge.warp.posecache`).
2. :meth:`~WarpPlanner.refine`: the content-aware alternation
   (:func:`~adaproj_edge.warp.engine.refine`, or the paper's as written) started from
   step 1's positions.

Coarse to fine (``PlanSettings.refine_factor`` > 1, the device's setting)
    Step 2 runs on a grid ``refine_factor`` times coarser whose vertices are a subset
    of the fine grid's. What it changes — the content coordinate of each coarse vertex
    minus the fine content-free warp's there — is interpolated bilinearly to the fine
    vertices and added to the fine content-free warp: the surface's detail (creases)
    comes from the fine solve, the smooth content-aware redistribution from the coarse
    one. A result that folds a fine triangle falls back to the content-free warp.

Warm starts (``PlanSettings.warm_start``)
    The planner keeps its last coarse solution; the next refinement of (nearly) the
    same surface starts from it and takes at most ``warm_iterations`` steps.

Anchored placement (``PlanSettings.anchor_rel``, off by default)
    The planner keeps the projector pixel where its last warp showed the content's
    centre; a content-free warp of (nearly) the same surface keeps the content there
    while the rectangle stays nearly as large as the largest
    (:func:`~adaproj_edge.warp.placement.place`'s ``anchor``), and its refinement keeps
    it too: consecutive estimates of a corner from a still device no longer move the
    content along the ridge.

Video frames (``refine(..., frame_dt=dt)``)
    Refined on the full grid (``PlanSettings.temporal.full_grid``, the default; the
    refinement grid without it, as in ``temporal.LOW_PASS``), the saliency
    weights graded, a warm start takes at most
    ``PlanSettings.temporal.steps`` steps (none while the content map stands still and
    the last refinement has converged)
    and the result goes through the planner's
    :class:`~adaproj_edge.warp.temporal.WarpSmoother`, so the warp follows a moving
    subject smoothly and stands still on a still scene (:mod:`adaproj_edge.warp.temporal`).

This file is about 600 lines on purpose: it is the one place that decides how a warp is
made (which grid, warm or cold, guarded or not, coarse or fine); the steps it chooses
between live in modules of their own (``engine``, ``guard``, ``adaptive``, ``temporal``,
``coarse``, ``posecache``).

Full grid (``refine_factor`` 1, :func:`compute_warp`)
    The grid is first refined where the surface bends faster than it samples it
    (``WarpSettings.adaptive``, :mod:`~adaproj_edge.warp.adaptive`); our alternation
    starts from the conformal warp (:func:`~adaproj_edge.warp.engine.content_aware`,
    no content-free solve needed when some but not all content is salient).

Never worse than conformal
    Every content-aware result (full grid or coarse) is checked against the conformal
    warp on the salient region by :func:`~adaproj_edge.warp.guard.guard`; ``meta``
    ``guard`` says what was kept and why.

:func:`compute_warp` is the one-shot call (the CLI, the renderer, the replay's
ground truth): a planner with the full-grid refinement and no state kept.

Pure: no clock, no hardware; the caller times the steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.errors import InputError, WarpError
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import carry_through_triangles, grid_triangles
from adaproj_edge.warp.adaptive import adaptive_mesh
from adaproj_edge.warp.coarse import (
    coarse_cells_of,
    coarse_indices,
    filled_by_shapes,
    upsample_field,
)
from adaproj_edge.warp.engine import (
    FAST,
    Backend,
    WarpSettings,
    content_aware,
    make_warp,
    paper_result,
    refine,
    refine_as_paper,
    standard_warp,
)
from adaproj_edge.warp.fallback import (
    Down,
    Solved,
    Step,
    chain,
    chain_of,
    keystone_surface,
    repair,
)
from adaproj_edge.warp.guard import conformal_measure, guard, guard_grid
from adaproj_edge.warp.mesh import MeshGeometry, WarpCache
from adaproj_edge.warp.orientation import fold_count
from adaproj_edge.warp.placement import Placement, place, turned_with_mesh
from adaproj_edge.warp.posecache import surfaces_match
from adaproj_edge.warp.temporal import GradedContentMap, TemporalWarpSettings, WarpSmoother
from adaproj_edge.warp.warpmap import Grid, Warp

StepHook = Callable[[], None]


@dataclass
class ContentFreeWarp:
    """Step 1's result: the content-free warp and what a refinement starts from.

    Attributes
    ----------
    warp : Warp
        The content-free warp on the full grid.
    depth : (R, C) float array
        The lattice depth of the surface it was made for (NaN where unknown).
    v_conformal, v : (n, 2) float arrays
        The conformal and the content-free positions of the mesh's vertices.
    placement : Placement
        The content's placement on ``v``.
    verts : (n,) int array
        The full-grid indices of the mesh's vertices.
    mesh : MeshGeometry
        The full grid's mesh (what a coarse refinement is guarded on).
    up : (3,) float array
        The "up" (frame P) the content was placed upright for.
    conformal_placement : Placement
        The content's placement on ``v_conformal`` (the guard's yardstick; made when
        first asked for: a content-free update never needs it).
    refinement_meshes : dict
        The coarse meshes refinements of this warp ran on, by grid: made once, from the
        surface of the first refinement (later ones - the device's, of surfaces within
        its pose cache's tolerance of this one - reuse it, as they reuse this warp).
    known_guard : (content map, up, memo) or None
        What the guard of its coarse-to-fine refinements measured of the conformal warp
        alone, for that content map (the same object) and "up"
        (:meth:`guard_memo`).
    """

    warp: Warp
    depth: FloatArray
    v_conformal: FloatArray
    v: FloatArray
    placement: Placement
    verts: IntArray
    mesh: MeshGeometry
    up: FloatArray
    known_conformal_placement: Placement | None = field(default=None, repr=False)
    refinement_meshes: dict[str, MeshGeometry] = field(
        default_factory=dict, repr=False, compare=False
    )
    known_guard: tuple[ContentMap, FloatArray, dict[str, Any]] | None = field(
        default=None, repr=False, compare=False
    )

    @property
    def step(self) -> str:
        """The step of the chain (:mod:`~adaproj_edge.warp.fallback`) this warp ended
        at: ``content-free`` when the surface as measured carried it."""
        return chain_of(self.warp)[0]

    @property
    def conformal_placement(self) -> Placement:
        """The content's placement on ``v_conformal`` (made once, when first used)."""
        if self.known_conformal_placement is None:
            self.known_conformal_placement = place(
                self.mesh, self.v_conformal, self.warp.content_size, self.up
            )
        return self.known_conformal_placement

    def guard_memo(
        self, content_map: ContentMap, up: FloatArray | tuple[float, ...]
    ) -> dict[str, Any]:
        """Where the guard of this warp's refinements keeps what it measured of the
        conformal warp alone (:func:`~adaproj_edge.warp.guard.guard_grid`'s ``memo``): the
        same for every refinement with ``content_map`` (the same object) and ``up``, and
        made again for another."""
        up_p = np.asarray(up, dtype=np.float64)
        known = self.known_guard
        if known is None or known[0] is not content_map or not np.array_equal(known[1], up_p):
            known = self.known_guard = (content_map, up_p.copy(), {})
        return known[2]

    def prepare(self, content_map: ContentMap, up: FloatArray | tuple[float, ...]) -> None:
        """Make ahead what a coarse-to-fine refinement of this warp with ``content_map``
        and ``up`` measures of it alone (its first one would): the conformal placement
        (:attr:`conformal_placement`) and the guard's measure of the conformal warp on
        the subject (:meth:`guard_memo`). The same values as made on first use, so the
        same warps; a device that has a frame to spare before it refines (settled, the
        content-free warp made the frame before) spends it so. Nothing for a warp down
        the chain (never refined)."""
        if self.step != "content-free":
            return
        conformal = (self.v_conformal, self.conformal_placement)
        conformal_measure(self.mesh, conformal, content_map, self.guard_memo(content_map, up))

    def matches(self, depth: FloatArray, max_rel: float, min_overlap: float) -> bool:
        """Whether the lattice ``depth`` is (nearly) the surface this warp was made for
        (:func:`~adaproj_edge.warp.posecache.surfaces_match`)."""
        return surfaces_match(depth, self.depth, max_rel, min_overlap)


@dataclass(frozen=True)
class PlanSettings:
    """How a planner refines.

    Attributes
    ----------
    refine_factor : int
        The content-aware grid is this many times coarser than the warp grid (1: the
        full grid, as :func:`compute_warp`).
    warm_start : bool
        Start a refinement from the last solution when it was made for (nearly) the
        same surface (within ``warm_rel``, median relative depth).
    warm_rel : float
    warm_iterations : int
        At most this many steps from a warm start.
    anchor_rel : float
        A content-free placement keeps the content where the planner's last one put it
        when made for (nearly) the same surface (within this median relative depth:
        the hand's sway and the depth's noise, not a re-aim; 0, the default: never).
        Off by default: the anchor is a projector pixel, and on a hand-held corner
        (a replayed session with tremor) it raised the stabilised jitter, where the
        placement alone no longer jumped.
    temporal : TemporalWarpSettings
        Steps per video frame and the smoothing in time (refinements with
        ``frame_dt``).
    """

    refine_factor: int = 1
    warm_start: bool = False
    warm_rel: float = 0.01
    warm_iterations: int = 4
    anchor_rel: float = 0.0
    temporal: TemporalWarpSettings = field(default_factory=TemporalWarpSettings)


@dataclass(frozen=True)
class _Solution:
    """A content-aware result kept for the next warm start."""

    v: FloatArray
    placement: Placement
    verts: IntArray
    start: ContentFreeWarp  # made for the surface of ``depth``
    depth: FloatArray
    factor: int  # on the grid this many times coarser than the warp grid
    origin: FloatArray  # the positions ``placement``'s rotation was made upright for


def _surface_depth(surface: Surface) -> FloatArray:
    depth = surface.points[..., 2].astype(np.float64)
    depth.setflags(write=False)  # kept by the planner and its warps, never changed
    return depth


def _may_rule(start: ContentFreeWarp, rows: IntArray, cols: IntArray) -> NDArray[np.bool_] | None:
    """Where a coarse grid on ``start``'s fine vertex ``rows`` x ``cols`` may look for
    a straight crease between curved sides: next to one the fine grid's mesh found (the
    same surface, its sides' patches fitted from cells half as wide). Elsewhere the
    coarse mesh's rough triangles hold none to find (on sensed depth: the depth smoothed
    across a silhouette, tried at ~0.5 ms each). None (everywhere) on the fine grid
    itself."""
    fine = start.mesh
    if rows.size == fine.grid.rows + 1 and cols.size == fine.grid.cols + 1:
        return None
    found = fine.topology.rows[fine.ruled]
    return coarse_cells_of(found, fine.grid.cols, rows, cols)


class WarpPlanner:
    """Makes the warps of one projector and grid; keeps solver structures (``cache``)
    and, with warm starts, its last solution.

    Parameters
    ----------
    projector : Projector
        The projector frame.
    grid : Grid, optional
        The warp grid (default 20x20).
    plan : PlanSettings, optional
        Coarse-to-fine factor and warm starts (default: full grid, no state).
    cache : WarpCache, optional
        Mesh topologies and solver structures kept between calls.
    backend : Backend
        The solves (:data:`~adaproj_edge.warp.engine.FAST`, or the reference).
    """

    def __init__(
        self,
        projector: Projector,
        grid: Grid | None = None,
        plan: PlanSettings | None = None,
        cache: WarpCache | None = None,
        backend: Backend = FAST,
    ) -> None:
        self.projector = projector
        self.grid = grid or Grid()
        self.plan_settings = p = plan or PlanSettings()
        self.cache = cache
        self.backend = backend
        self.rows = coarse_indices(self.grid.rows, p.refine_factor)
        self.cols = coarse_indices(self.grid.cols, p.refine_factor)
        self.coarse_grid = Grid(cols=self.cols.size - 1, rows=self.rows.size - 1)
        self._last: _Solution | None = None
        self._anchor: tuple[FloatArray, FloatArray] | None = None  # depth, centre's uv
        self._depth: tuple[NDArray[np.float32], FloatArray] | None = None  # points, depth
        self.smoother = WarpSmoother(p.temporal)

    def _depth_of(self, surface: Surface) -> FloatArray:
        """The lattice depth of ``surface`` (float64, read-only), kept for the last
        surface's points: a clip asks for the same surface's on every frame, twice, and
        each copy at 1280x800 costs ~1.5 ms of a 33 ms frame."""
        kept = self._depth
        if kept is None or kept[0] is not surface.points:
            kept = self._depth = (surface.points, _surface_depth(surface))
        return kept[1]

    def forget(self) -> None:
        """Drop the solution kept for warm starts, the last placement's anchor and the
        video frames' past."""
        self._last = None
        self._anchor = None
        self.smoother.reset()

    def _anchored(
        self,
        mesh: MeshGeometry,
        v: FloatArray,
        content_size: tuple[int, int],
        up: FloatArray | tuple[float, ...],
        depth: FloatArray,
    ) -> Placement:
        """The content-free placement of ``v`` for the surface of lattice ``depth``:
        kept where the last one was when that was made for the same surface (within
        ``anchor_rel``; :func:`~adaproj_edge.warp.placement.place`), and remembered."""
        anchor = None
        rel = self.plan_settings.anchor_rel
        if (
            self._anchor is not None
            and rel > 0
            and surfaces_match(depth, self._anchor[0], rel, 0.5)
        ):
            anchor = self._anchor[1]
        placement = place(mesh, v, content_size, np.asarray(up, dtype=np.float64), anchor=anchor)
        self._anchor = None if placement.uv is None else (depth, placement.uv)
        return placement

    def _shown(self, surface: Surface, warp: Warp) -> Warp:
        """``warp`` (made for ``surface``), its content's centre remembered as the next
        placement's anchor."""
        rows, cols = warp.image_xy.shape[:2]
        tris = grid_triangles(rows - 1, cols - 1)
        w, h = warp.content_size
        centre = np.array([[0.5 * (w - 1), 0.5 * (h - 1)]])
        q, g = warp.image_xy.reshape(-1, 2)[tris], warp.grid_uv.reshape(-1, 2)[tris]
        uv = carry_through_triangles(q, g, centre)[0]
        if np.all(np.isfinite(uv)):
            self._anchor = (self._depth_of(surface), uv)
        return warp

    # ------------------------------------------------------------------ steps
    def standard(self, content_size: tuple[int, int]) -> Warp:
        """The content letterboxed on the frame (no pre-warp)."""
        return standard_warp(self.projector, content_size, self.grid)

    def conformal(
        self, surface: Surface, content_size: tuple[int, int], settings: WarpSettings
    ) -> Warp:
        """E_a alone with uniform weights (the iLamps-style baseline)."""
        settings = replace(settings, grid=self.grid)
        mesh, extra = self._mesh(surface, settings)
        v = self.backend.conformal(mesh)
        placement = place(mesh, v, content_size, settings.up)
        warp = make_warp(mesh, v, placement, surface, content_size, settings, 0, 0.0)
        warp.meta.update(extra)
        return warp

    def _mesh(
        self, surface: Surface, settings: WarpSettings
    ) -> tuple[MeshGeometry, dict[str, Any]]:
        """The full-grid mesh, refined where the surface bends faster than the grid
        samples it (``settings.adaptive``; full-grid planners only: the device's
        coarse-to-fine path keeps its grid); meta says how."""
        surface.check_usable()
        adaptive = settings.adaptive and self.plan_settings.refine_factor <= 1
        return adaptive_mesh(surface, self.grid, self.cache, adaptive)

    def content_free(
        self, surface: Surface, content_size: tuple[int, int], settings: WarpSettings
    ) -> ContentFreeWarp:
        """Step 1: E' = E_a + lambda E_r for ``surface`` (paper eq. 7) on the full grid,
        placed in the content; raises :class:`~adaproj_edge.errors.WarpError` when the
        surface cannot carry a warp."""
        return self._content_free(surface, content_size, settings)[0]

    def _content_free(
        self, surface: Surface, content_size: tuple[int, int], settings: WarpSettings
    ) -> tuple[ContentFreeWarp, MeshGeometry]:
        """Step 1, down the chain (:mod:`~adaproj_edge.warp.fallback`) when the surface
        as measured cannot carry it: repaired, then the dominant plane's keystone."""
        settings = replace(settings, grid=self.grid)
        first: Solved | None = None  # the solve a repair starts from (not refined)
        try:
            mesh, extra = self._mesh(surface, settings)
            for held in (mesh, mesh.without_planes()) if mesh.planar.any() else (mesh,):
                # the snapped planes held undistorted, unless that folds the rest: then
                # the uniform weights (a wall seen grazing beside a floor takes it all)
                try:
                    v_conf = self.backend.conformal(held)
                    v, _ = self.backend.content_free(held, v_conf, settings.lam)
                    first = None if extra else Solved(held, v_conf, v)
                    return self._start_of(
                        surface, surface, held, extra, v_conf, v, content_size, settings
                    )
                except WarpError as e:
                    error = e
            raise error
        except WarpError as e:
            down: Down = [("content-free", str(e))]
        b = self.backend
        try:
            fixed = repair(
                surface, self.grid, self.cache, b.conformal, b.content_free, settings.lam, first
            )
            extra = {"repair_dropped": fixed.dropped}
            return self._start_of(
                surface, surface, fixed.mesh, extra, fixed.v_conformal, fixed.v, content_size,
                settings, "repaired", down,
            )  # fmt: skip
        except WarpError as e:
            down.append(("repaired", str(e)))
        try:
            plane = keystone_surface(surface)
            mesh = MeshGeometry.build(plane, self.grid, self.cache)
            v_conf = b.conformal(mesh)
            v, _ = b.content_free(mesh, v_conf, settings.lam)
            return self._start_of(
                plane, surface, mesh, {}, v_conf, v, content_size, settings, "keystone", down
            )
        except WarpError as e:
            down.append(("keystone", str(e)))
        raise WarpError("; ".join(f"{step}: {reason}" for step, reason in down))

    def _start_of(
        self,
        shown: Surface,
        measured: Surface,
        mesh: MeshGeometry,
        extra: dict[str, Any],
        v_conf: FloatArray,
        v: FloatArray,
        content_size: tuple[int, int],
        settings: WarpSettings,
        step: Step = "content-free",
        down: Down | None = None,
    ) -> tuple[ContentFreeWarp, MeshGeometry]:
        """The content-free warp of ``mesh`` (of the surface ``shown``) with positions
        ``v`` (conformal ``v_conf``), made for the ``measured`` surface (the pose cache
        matches it), ended at ``step`` of the chain after ``down``."""
        depth = self._depth_of(measured)
        placement = self._anchored(mesh, v, content_size, settings.up, depth)
        warp = make_warp(mesh, v, placement, shown, content_size, settings, 0, 0.0)
        warp.meta.update(extra)
        warp.meta["chain"] = chain(step, down)
        up = np.asarray(settings.up, dtype=np.float64)
        cf = ContentFreeWarp(warp, depth, v_conf, v, placement, mesh.verts.copy(), mesh, up)
        return cf, mesh

    def with_up(
        self, start: ContentFreeWarp, up: FloatArray | tuple[float, ...]
    ) -> ContentFreeWarp:
        """``start`` placed upright for another "up" (frame P): the solves depend on
        the surface alone, so only the placements (and the warp's content coordinates)
        are made again - a device turned about its axis in front of the same surface
        needs no new solve. The refinement meshes are shared."""
        mesh = start.mesh
        size = start.warp.content_size
        up_p = np.asarray(up, dtype=np.float64)
        placement = self._anchored(mesh, start.v, size, up_p, start.depth)
        flat = np.full((start.warp.grid_uv.shape[0] * start.warp.grid_uv.shape[1], 2), np.nan)
        flat[mesh.verts] = placement.apply(start.v)
        warp = replace(
            start.warp, image_xy=flat.reshape(start.warp.image_xy.shape), meta=dict(start.warp.meta)
        )
        return replace(
            start,
            warp=warp,
            placement=placement,
            up=up_p,
            known_conformal_placement=None,
            known_guard=None,
        )

    def _conformal_start(
        self, surface: Surface, content_size: tuple[int, int], settings: WarpSettings
    ) -> tuple[MeshGeometry, dict[str, Any], FloatArray, Placement]:
        """The mesh (and its meta), the conformal positions and their placement: what
        our alternation starts from and the guard's yardstick."""
        mesh, extra = self._mesh(surface, settings)
        v_conf = self.backend.conformal(mesh)
        return mesh, extra, v_conf, place(mesh, v_conf, content_size, settings.up)

    def refine(
        self,
        surface: Surface,
        content_map: ContentMap,
        settings: WarpSettings,
        start: ContentFreeWarp,
        on_step: StepHook | None = None,
        frame_dt: float | None = None,
    ) -> Warp:
        """Step 2: the content-aware alternation on the (coarse) grid, combined with
        the fine content-free warp ``start`` (made for this surface, or one within a
        pose cache's tolerance of it). ``on_step`` is called after every step (a
        caller's stopwatch). ``frame_dt``: this is a video frame shown ``frame_dt``
        seconds after the last one (bounded warm steps, smoothed in time).

        Never raises for the refinement's sake: when it fails, or ``start`` is not the
        surface's own content-free warp (repaired, keystone), the content-free warp
        ``start`` is the answer, its ``meta["chain"]`` saying why."""
        if start.step != "content-free":
            return start.warp  # a repaired mesh or a plane: nothing to refine on
        try:
            warp = self._refine_on(surface, content_map, settings, start, on_step, frame_dt)
        except WarpError as e:
            return _instead(start, str(e))
        return self._shown(surface, warp)

    def _refine_on(
        self,
        surface: Surface,
        content_map: ContentMap,
        settings: WarpSettings,
        start: ContentFreeWarp,
        on_step: StepHook | None,
        frame_dt: float | None,
    ) -> Warp:
        held = None if frame_dt is None else self.smoother.held(content_map, start)
        if held is not None and frame_dt is not None:  # the content stands still: so
            return self.smoother.smooth(held, start, frame_dt)  # does the warp
        rows, cols, grid = self._refinement_grid(start, frame_dt is not None)
        mesh = start.refinement_meshes.get(str(grid))
        if mesh is None:
            coarse_uv = start.warp.grid_uv[np.ix_(rows, cols)]
            mesh = MeshGeometry.build(
                surface,
                grid,
                self.cache,
                coarse_uv,
                _may_rule(start, rows, cols),
                along=start.mesh.along,  # the full grid's triangles as its start had them
            )
            start.refinement_meshes[str(grid)] = mesh
        depth = self._depth_of(surface)
        if frame_dt is None:
            return self._refine(mesh, depth, content_map, settings, start, on_step, surface=surface)
        graded = GradedContentMap.of(content_map, self.plan_settings.temporal.band)
        warp = self._refine(
            mesh, depth, graded, settings, start, on_step, frame_dt, surface=surface
        )
        self.smoother.refined(warp, content_map, start)
        return self.smoother.smooth(warp, start, frame_dt)

    def _refine(
        self,
        mesh: MeshGeometry,
        depth: FloatArray,
        content_map: ContentMap,
        settings: WarpSettings,
        start: ContentFreeWarp,
        on_step: StepHook | None = None,
        frame_dt: float | None = None,
        surface: Surface | None = None,
    ) -> Warp:
        """:meth:`refine` (before any smoothing) on the refinement grid's ``mesh`` of
        the surface of lattice ``depth``; the guard scores as displayed on ``surface``
        (the one the meshes were built from) when it is given."""
        fine = start.warp
        factor = self._factor(frame_dt is not None)
        c_rows, c_cols, grid = self._refinement_grid(start, frame_dt is not None)
        coarse_settings = replace(settings, grid=grid)
        fine_cols = fine.grid_uv.shape[1]
        to_fine = (c_rows[:, None] * fine_cols + c_cols[None, :]).ravel()
        v, placement, warm = self._start(mesh, start, to_fine, depth, content_map, settings, factor)
        # the positions the placement's rotation is upright for: a warm start's chain's
        origin = self._last.origin if warm and self._last is not None else v
        v_conf = self._on_mesh(start.v_conformal, start, to_fine, mesh.verts)
        extra: dict[str, Any] = {}
        if warm:
            p = self.plan_settings
            steps = p.warm_iterations if frame_dt is None else p.temporal.steps
            coarse_settings = replace(
                coarse_settings, max_iterations=min(settings.max_iterations, steps)
            )
        known = bool(np.isfinite(v_conf).all())
        # a clip's frames go on from a guarded first solve: guarding each frame anew
        # would switch between warps from one frame to the next
        in_clip = warm and frame_dt is not None
        if settings.alternation == "paper":
            if not known:
                v_conf = self.backend.conformal(mesh)
            v, its, frac = refine_as_paper(mesh, v_conf, v, placement, content_map, coarse_settings)
        elif known and not warm and factor <= 1:
            # our alternation from the conformal warp, guarded (engine.content_aware)
            p_conf = start.conformal_placement
            ours = content_aware(
                mesh,
                v_conf,
                p_conf,
                content_map,
                coarse_settings,
                self.backend,
                on_step,
                surface=surface,
            )
            if ours is None:  # nothing or everything salient: E' is the answer
                its, frac = 0, float(content_map.weights(placement.apply(v)).mean())
            else:
                v, placement, its, frac, guarded = ours
                extra.update(guarded)
                origin = v_conf
        else:
            v, placement, its, frac = refine(
                mesh, v, placement, content_map, coarse_settings, self.backend, on_step
            )
            if known and factor <= 1 and not in_clip:
                choice = guard(
                    mesh,
                    (v, placement),
                    (v_conf, start.conformal_placement),
                    content_map,
                    settings.up,
                    surface=surface,
                    flatten=True,
                )
                v, placement, extra["guard"] = choice.v, choice.placement, choice.meta
                if str(choice.meta.get("choice", "")).startswith("conformal"):
                    origin = v_conf  # placed upright for it
        if self.plan_settings.warm_start:
            self._last = _Solution(v, placement, mesh.verts.copy(), start, depth, factor, origin)
        shown = placement  # the alternation's own placement: what a warm start goes on from
        if settings.alternation == "ours":
            size = fine.content_size
            shown = turned_with_mesh(mesh, origin, v, placement, size, settings.up)
        coarse_xy = np.full((to_fine.size, 2), np.nan)
        coarse_xy[mesh.verts] = shown.apply(v)
        rows, cols = fine.grid_uv.shape[:2]
        if factor <= 1:
            image_xy = coarse_xy.reshape(rows, cols, 2)
        else:
            delta = (
                coarse_xy.reshape(c_rows.size, c_cols.size, 2)
                - fine.image_xy[np.ix_(c_rows, c_cols)]
            )
            image_xy = fine.image_xy + upsample_field(delta, c_rows, c_cols, (rows, cols))
            if not in_clip:
                image_xy, extra["guard"] = guard_grid(
                    image_xy,
                    start.mesh,
                    (start.v_conformal, start.conformal_placement),
                    content_map,
                    settings.up,
                    start.guard_memo(content_map, settings.up),
                )
        meta = {
            **fine.meta,
            "alternation": settings.alternation,
            "iterations": its,
            "salient_vertex_fraction": frac,
            **extra,
            "chain": chain("content-aware"),
        }
        if factor > 1:
            meta["refine_grid"] = str(self.coarse_grid)
        warp = Warp(
            fine.grid_uv, image_xy, fine.content_size, fine.projector, meta, depth=fine.depth
        )
        if factor > 1:
            folds = fold_count(warp)
            if folds:
                return _instead(start, f"the refinement folds {folds} triangles", folds)
        return warp

    def plan(
        self,
        surface: Surface,
        content_size: tuple[int, int],
        content_map: ContentMap | None,
        settings: WarpSettings,
    ) -> Warp:
        """The warp of ``settings.mode`` in one call (no pose cache)."""
        if settings.mode == "standard":
            return self.standard(content_size)
        if settings.mode == "conformal":
            return self.conformal(surface, content_size, settings)
        if settings.alternation == "paper" and self.backend.paper and content_map is not None:
            return paper_result(surface, content_size, content_map, settings, self.backend.paper)
        if (
            self.plan_settings.refine_factor <= 1
            and content_map is not None
            and settings.alternation == "ours"
        ):
            # the full grid: our alternation needs no content-free solve when some but
            # not all content is salient (what content_free + refine give, sooner)
            full = replace(settings, grid=self.grid)
            try:
                mesh, extra, v_conf, p_conf = self._conformal_start(surface, content_size, full)
                ours = content_aware(
                    mesh, v_conf, p_conf, content_map, full, self.backend, surface=surface
                )
                if ours is not None:
                    v, placement, its, frac, guarded = ours
                    placement = turned_with_mesh(mesh, v_conf, v, placement, content_size, full.up)
                    warp = make_warp(mesh, v, placement, surface, content_size, full, its, frac)
                    warp.meta.update(extra, **guarded)
                    warp.meta["chain"] = chain("content-aware")
                    return warp
            except WarpError as e:  # down the chain, from the content-free warp
                start, _ = self._content_free(surface, content_size, settings)
                step, down = chain_of(start.warp)
                down = [("content-aware", str(e)), *down]
                meta = {**start.warp.meta, "chain": chain(step, down)}
                return replace(start.warp, meta=meta)
        start, mesh = self._content_free(surface, content_size, settings)
        if content_map is None:
            return start.warp
        if self.plan_settings.refine_factor > 1 or start.step != "content-free":
            return self.refine(surface, content_map, settings, start)
        # the full grid: refine on the content-free step's own mesh
        try:
            return self._refine(mesh, start.depth, content_map, settings, start, surface=surface)
        except WarpError as e:
            return _instead(start, str(e))

    # ------------------------------------------------------------------ helpers
    def _factor(self, clip: bool) -> int:
        """The refinement's coarse-to-fine factor: the plan's, or 1 for a clip's frame
        (``clip``) when ``PlanSettings.temporal.full_grid``."""
        p = self.plan_settings
        return 1 if clip and p.temporal.full_grid else p.refine_factor

    def _refinement_grid(
        self, start: ContentFreeWarp, clip: bool = False
    ) -> tuple[IntArray, IntArray, Grid]:
        """The refinement grid's fine rows and columns and its Grid: every fine vertex
        of ``start``'s (maybe adaptively refined) grid, or the coarse subset (``clip``:
        a clip's frame, see :meth:`_factor`)."""
        if self._factor(clip) > 1:
            return self.rows, self.cols, self.coarse_grid
        rows, cols = start.warp.grid_uv.shape[:2]
        return np.arange(rows), np.arange(cols), Grid(cols=cols - 1, rows=rows - 1)

    def _on_mesh(
        self, v_fine: FloatArray, start: ContentFreeWarp, to_fine: IntArray, verts: IntArray
    ) -> FloatArray:
        """Fine positions ``v_fine`` (of ``start.verts``) at the vertices ``verts`` of a
        coarse mesh (NaN where the fine mesh has none)."""
        n_fine = start.warp.grid_uv.shape[0] * start.warp.grid_uv.shape[1]
        full = np.full((n_fine, 2), np.nan)
        full[start.verts] = v_fine
        out: FloatArray = full[to_fine][verts]
        return out

    def _start(
        self,
        mesh: MeshGeometry,
        start: ContentFreeWarp,
        to_fine: IntArray,
        depth: FloatArray,
        content_map: ContentMap,
        settings: WarpSettings,
        factor: int,
    ) -> tuple[FloatArray, Placement, bool]:
        """Where the alternation starts: the last solution (warm, made on the grid of
        the same ``factor``), the content-free positions at the coarse vertices (those
        the fine mesh misses - at a hole's edge on sensed depth - placed by the coarse
        triangles' shapes around them, :func:`~adaproj_edge.warp.coarse.filled_by_shapes`:
        a fresh solve's placement cost as much as the rest of a first refinement and
        put the content elsewhere than the content-free warp shows it), or, where no
        triangle reaches them, a fresh solve."""
        last = self._last
        if (
            self.plan_settings.warm_start
            and last is not None
            and last.factor == factor
            and np.array_equal(last.verts, mesh.verts)
            and surfaces_match(depth, last.depth, self.plan_settings.warm_rel, 0.97)
        ):
            return last.v, last.placement, True  # near the answer already
        v0 = self._on_mesh(start.v, start, to_fine, mesh.verts)
        filled = filled_by_shapes(v0, mesh.tris, mesh.coords)
        if filled is not None:  # in the content-free warp's placement: no new one
            return filled, start.placement, False
        v, _ = self.backend.content_free(mesh, self.backend.conformal(mesh), settings.lam)
        return v, place(mesh, v, content_map.content_size, settings.up), False


def _instead(start: ContentFreeWarp, reason: str, folds: int = 0) -> Warp:
    """The content-free warp ``start``, shown because the refinement failed for
    ``reason`` (``folds``: it folded that many fine triangles)."""
    meta = {**start.warp.meta, "chain": chain("content-free", [("content-aware", reason)])}
    if folds:
        meta["refine_folds"] = folds
    return replace(start.warp, meta=meta)


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
    backend : Backend
        The solves (the fast ones, or the reference for comparison).
    cache : WarpCache, optional
        Keeps the mesh topology and solver structures between calls (a scene seen
        again skips that set-up).

    Returns
    -------
    Warp
        ``meta`` holds the mode, grid, iterations and salient vertex fraction.
    """
    settings = settings or WarpSettings()
    w, h = content_size
    if w < 2 or h < 2:
        raise InputError(f"content size {w}x{h} is too small")
    cmap: ContentMap | None = None
    if content_map is not None and settings.mode == "content":
        values = content_map.values if isinstance(content_map, ContentMap) else content_map
        if np.ndim(values) != 2:
            raise InputError(f"content map must be a 2D array, got shape {np.shape(values)}")
        cmap = ContentMap(np.asarray(values, np.float32), content_size, settings.threshold)
    planner = WarpPlanner(surface.projector, settings.grid, PlanSettings(), cache, backend)
    return planner.plan(surface, content_size, cmap, settings)
