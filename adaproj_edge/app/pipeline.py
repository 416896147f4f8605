"""The warp pipeline of the runtime: surface -> content-free warp (cached per pose) ->
content-aware refinement on a coarse grid (warm-started) -> display maps.

Built from the engine's pieces (:mod:`adaproj_edge.warp.engine`), so the runtime can
keep the solver's positions between updates.

Content-aware refinement, coarse to fine
    The content-free warp is solved on the full grid (20x20 by default) and cached per
    pose. The content-aware alternation runs on a grid ``refine_factor`` times coarser
    whose vertices are a subset of the fine grid's; it starts from the last solution
    when that was made for (nearly) this surface, else from the cached content-free
    positions restricted to the coarse vertices. What it changes — the content
    coordinate of each coarse vertex minus the fine content-free warp's there — is
    interpolated bilinearly to the fine vertices and added to the fine content-free
    warp: the surface's detail (creases) comes from the fine solve, the smooth
    content-aware redistribution from the coarse one.

Display maps
    Built at 1/``map_scale`` resolution by perspective-correct interpolation of the mesh
    (:class:`~adaproj_edge.render.maps.PixelWeights`, computed once per pose and reused
    by every warp of that pose) and interpolated up to the frame by ``cv2.resize``
    inside the fixed-point map conversion; the per-pixel surface map of
    :func:`~adaproj_edge.render.maps.map_from_warp` costs about a second on the board.

Stage times are measured with ``time.perf_counter`` and only reported; no decision
depends on them.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.app.posecache import CachedWarp
from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import grid_triangles
from adaproj_edge.render.frame import RemapMaps
from adaproj_edge.render.maps import PixelLayout, PixelWeights, map_from_warp
from adaproj_edge.warp.engine import FAST, WarpSettings, make_warp, refine, standard_warp
from adaproj_edge.warp.mesh import MeshGeometry, WarpCache
from adaproj_edge.warp.placement import Placement, place
from adaproj_edge.warp.warpmap import Grid, Warp

log = logging.getLogger(__name__)


@dataclass
class StageTimes:
    """Wall-clock seconds per stage, for the summary and the benchmark: the last
    ``keep`` samples of each stage."""

    keep: int = 20000
    samples: dict[str, deque[float]] = field(default_factory=dict)

    def add(self, stage: str, seconds: float) -> None:
        if stage not in self.samples:
            self.samples[stage] = deque(maxlen=self.keep)
        self.samples[stage].append(seconds)

    def summary(self) -> dict[str, dict[str, float]]:
        out = {}
        for stage, xs in sorted(self.samples.items()):
            a = np.asarray(xs) * 1e3
            out[stage] = {
                "n": int(a.size),
                "median_ms": round(float(np.median(a)), 3),
                "p95_ms": round(float(np.percentile(a, 95)), 3),
            }
        return out


class _Timer:
    def __init__(self, times: StageTimes, stage: str) -> None:
        self.times, self.stage = times, stage

    def __enter__(self) -> None:
        self.t0 = time.perf_counter()

    def __exit__(self, *exc: object) -> None:
        self.times.add(self.stage, time.perf_counter() - self.t0)


def scaled_projector(projector: Projector, factor: int) -> Projector:
    """The projector frame at 1/``factor`` resolution (pixel centres at integers)."""
    s = 1.0 / factor
    S = np.array([[s, 0.0, 0.5 * s - 0.5], [0.0, s, 0.5 * s - 0.5], [0.0, 0.0, 1.0]])
    return Projector(S @ projector.K, projector.width // factor, projector.height // factor)


def display_map(warp: Warp, factor: int) -> NDArray[np.float32]:
    """The (H, W, 2) content map of ``warp`` for the full frame, interpolated
    perspective-correctly at 1/``factor`` resolution and scaled up (NaN: black)."""
    p = warp.projector
    if factor <= 1:
        return map_from_warp(warp)
    m = small_weights(warp, factor).map(warp.image_xy, warp.content_size)
    # align pixel centres: full-res pixel x sits at (x + 0.5) / factor - 0.5 coarse
    big = cv2.resize(m, (p.width, p.height), interpolation=cv2.INTER_LINEAR)
    return np.asarray(big, dtype=np.float32)


def small_weights(warp: Warp, factor: int, layout: PixelLayout | None = None) -> PixelWeights:
    """Pixel weights of ``warp``'s mesh (grid and vertex depths) at 1/``factor`` of the
    frame: one set per pose, shared by every warp of that mesh. ``layout``: the grid's
    layout at that resolution (:func:`small_layout`), when the caller keeps it."""
    small = scaled_projector(warp.projector, max(factor, 1))
    grid_uv = (warp.grid_uv + 0.5) / max(factor, 1) - 0.5
    return PixelWeights.build(grid_uv, warp.depth, small, layout=layout)


def small_layout(grid_uv: FloatArray, projector: Projector, factor: int) -> PixelLayout:
    """The pixel layout of the grid ``grid_uv`` at 1/``factor`` of the frame."""
    small = scaled_projector(projector, max(factor, 1))
    return PixelLayout.build((grid_uv + 0.5) / max(factor, 1) - 0.5, small)


def remap_maps(
    weights: PixelWeights, warp: Warp, scratch: NDArray[np.float32] | None = None
) -> RemapMaps:
    """The renderer's maps of ``warp`` through the reduced-resolution ``weights``
    (``scratch``: a reusable full-resolution float buffer, see RemapMaps.upsampled)."""
    small = weights.map(warp.image_xy, warp.content_size, clip=False)
    size = (warp.projector.width, warp.projector.height)
    return RemapMaps.upsampled(small, size, scratch)


def coarse_indices(cells: int, factor: int) -> NDArray[np.intp]:
    """Fine-grid vertex indices (0..``cells``) of a grid about ``factor`` times coarser
    (at least 2 cells; every index is a fine vertex, both ends included)."""
    m = max(2, -(-cells // max(factor, 1)))
    return np.unique(np.rint(np.linspace(0, cells, min(m, cells) + 1)).astype(np.intp))


def _linear_weights(coarse: NDArray[np.intp], n: int) -> FloatArray:
    """(n, len(coarse)) weights interpolating values at ``coarse`` indices linearly to
    every index 0..n-1."""
    x = np.arange(n, dtype=np.float64)
    j = np.clip(np.searchsorted(coarse, x, side="right") - 1, 0, coarse.size - 2)
    f = (x - coarse[j]) / (coarse[j + 1] - coarse[j])
    W = np.zeros((n, coarse.size))
    W[np.arange(n), j] = 1.0 - f
    W[np.arange(n), j + 1] += f
    return W


def upsample_field(
    values: FloatArray, rows: NDArray[np.intp], cols: NDArray[np.intp], shape: tuple[int, int]
) -> FloatArray:
    """Values (r, c, k) at the coarse vertices ``rows`` x ``cols`` interpolated
    bilinearly to every vertex of a (R, C) grid; unknown (NaN) coarse values take the
    nearest known one first."""
    known = np.isfinite(values).all(axis=-1)
    if not known.any():
        return np.zeros((*shape, values.shape[-1]))
    if not known.all():
        idx = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
        values = values[idx[0], idx[1]]
    Wr = _linear_weights(rows, shape[0])
    Wc = _linear_weights(cols, shape[1])
    out: FloatArray = np.einsum("ir,rck,jc->ijk", Wr, values, Wc)
    return out


def fold_count(warp: Warp) -> int:
    """Grid triangles (with all corners known) whose orientation in content space differs
    from the one they have in the projector frame."""
    rows, cols = warp.grid_uv.shape[:2]
    tris = grid_triangles(rows - 1, cols - 1)

    def cross(p: FloatArray) -> FloatArray:
        q = p.reshape(-1, 2)[tris]
        a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
        out: FloatArray = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        return out

    c, ref = cross(warp.image_xy), cross(warp.grid_uv)
    ok = np.isfinite(c)
    return int(np.sum(c[ok] * ref[ok] <= 0))


@dataclass
class Solution:
    """A coarse content-aware result kept for the next warm start."""

    v: FloatArray
    placement: Placement
    verts: NDArray[np.intp]
    iterations: int
    start: CachedWarp  # its ``depth`` is the surface this solution was made for


class WarpPipeline:
    """Computes the warps and maps the runtime shows.

    Parameters
    ----------
    projector : the projector frame
    grid : the warp grid (the engine's default 20x20)
    map_scale : the display map is built at 1/map_scale resolution
    warm_start : start the content-aware alternation from the last solution
    caching : keep mesh topologies and solver structures between updates
    refine_factor : the content-aware grid is this many times coarser than ``grid``
        (1: refine on the full grid)
    history : stage-time samples kept per stage
    """

    def __init__(
        self,
        projector: Projector,
        grid: Grid | None = None,
        map_scale: int = 4,
        warm_start: bool = True,
        caching: bool = True,
        refine_factor: int = 2,
        history: int = 20000,
    ) -> None:
        self.projector = projector
        self.grid = grid or Grid()
        self.map_scale = map_scale
        self.warm_start = warm_start
        self.refine_factor = refine_factor
        self.warm_rel = 0.01  # a solution warm-starts surfaces within 1 % depth
        self.warp_cache: WarpCache | None = WarpCache() if caching else None
        self.times = StageTimes(history)
        self.last: Solution | None = None
        self.rows = coarse_indices(self.grid.rows, refine_factor)
        self.cols = coarse_indices(self.grid.cols, refine_factor)
        self.coarse_grid = Grid(cols=self.cols.size - 1, rows=self.rows.size - 1)
        self._grid_uv = self.grid.vertices(projector)
        self._layout = small_layout(self._grid_uv, projector, map_scale)
        # the full-resolution float map on its way to the fixed-point maps, reused
        self._scratch = np.empty((projector.height, projector.width, 2), np.float32)

    def _weights(self, warp: Warp) -> PixelWeights:
        same = warp.grid_uv.shape == self._grid_uv.shape and np.array_equal(
            warp.grid_uv, self._grid_uv
        )
        return small_weights(warp, self.map_scale, self._layout if same else None)

    def timer(self, stage: str) -> _Timer:
        return _Timer(self.times, stage)

    def display_map(self, warp: Warp) -> NDArray[np.float32]:
        """The float map (H, W, 2) the renderer's maps of ``warp`` approximate, NaN where
        the pixel shows black (for scoring; not used to draw)."""
        return display_map(warp, self.map_scale)

    def maps(self, warp: Warp) -> RemapMaps:
        """The renderer's maps for any warp (one loaded at boot, say)."""
        with self.timer("map"):
            return remap_maps(self._weights(warp), warp, self._scratch)

    def plain(self, content_size: tuple[int, int]) -> tuple[Warp, RemapMaps]:
        """The content letterboxed on the frame (no pre-warp)."""
        surface = Surface(np.ones((2, 2, 3), np.float32), self.projector)
        warp = standard_warp(surface, content_size, self.grid)
        return warp, self.maps(warp)

    def content_free(
        self, surface: Surface, content_size: tuple[int, int], settings: WarpSettings
    ) -> CachedWarp:
        """E' = E_a + lambda E_r for ``surface`` (paper eq. 7), with the pixel weights of
        its mesh (its own display maps are made when it is first shown)."""
        settings = replace(settings, grid=self.grid)
        with self.timer("content_free"):
            surface.check_usable()
            mesh = MeshGeometry.build(surface, self.grid, self.warp_cache)
            v_conf = FAST.conformal(mesh)
            v, _ = FAST.content_free(mesh, v_conf, settings.lam)
            placement = place(mesh, v, content_size, settings.up)
            warp = make_warp(mesh, v, placement, surface, content_size, settings, 0, 0.0, {})
            pixels = self._weights(warp)
        depth = surface.points[..., 2].astype(np.float64)
        frames = int(surface.meta.get("frames", 1))
        return CachedWarp(warp, depth, v, placement, mesh.verts.copy(), pixels, frames=frames)

    def content_free_maps(self, entry: CachedWarp) -> RemapMaps:
        """The renderer's maps of a content-free warp (made once per entry)."""
        if entry.maps is None:
            with self.timer("map"):
                entry.maps = remap_maps(entry.pixels, entry.warp, self._scratch)
        return entry.maps

    def content_aware(
        self,
        surface: Surface,
        content_map: ContentMap,
        settings: WarpSettings,
        start: CachedWarp,
    ) -> tuple[Warp, RemapMaps]:
        """The content-aware alternation on the coarse grid, combined with the fine
        content-free warp ``start`` (made for this surface, or one within the pose
        cache's tolerance of it)."""
        with self.timer("content_aware"):
            warp = self._refine(surface, content_map, settings, start)
        with self.timer("map"):
            maps = remap_maps(start.pixels, warp, self._scratch)
        return warp, maps

    def _refine(
        self, surface: Surface, content_map: ContentMap, settings: WarpSettings, start: CachedWarp
    ) -> Warp:
        fine = start.warp
        if self.refine_factor <= 1:
            coarse_uv = fine.grid_uv
        else:
            coarse_uv = fine.grid_uv[np.ix_(self.rows, self.cols)]
        settings = replace(settings, grid=self.coarse_grid)
        mesh = MeshGeometry.build(surface, self.coarse_grid, self.warp_cache, coarse_uv)
        depth = surface.points[..., 2].astype(np.float64)
        last = self.last
        fine_cols = fine.grid_uv.shape[1]
        # the coarse vertices' indices in the fine grid
        to_fine = (self.rows[:, None] * fine_cols + self.cols[None, :]).ravel()
        start_v = np.full((fine.grid_uv.shape[0] * fine_cols, 2), np.nan)
        start_v[start.verts] = start.v
        v0 = start_v[to_fine][mesh.verts]
        if (
            self.warm_start
            and last is not None
            and np.array_equal(last.verts, mesh.verts)
            and last.start.matches(depth, self.warm_rel, 0.97)
        ):
            # near the answer already: a few steps are enough
            v, placement = last.v, last.placement
            settings = replace(settings, max_iterations=min(settings.max_iterations, 4))
        elif np.isfinite(v0).all():
            v, placement = v0, start.placement
        else:
            v, _ = FAST.content_free(mesh, FAST.conformal(mesh), settings.lam)
            placement = place(mesh, v, content_map.content_size, settings.up)
        v, placement, its, frac = refine(mesh, v, placement, content_map, settings, FAST)
        self.last = Solution(v, placement, mesh.verts.copy(), its, replace(start, depth=depth))
        coarse_xy = np.full((to_fine.size, 2), np.nan)
        coarse_xy[mesh.verts] = placement.apply(v)
        rows, cols = fine.grid_uv.shape[:2]
        delta = (
            coarse_xy.reshape(self.rows.size, self.cols.size, 2)
            - fine.image_xy[np.ix_(self.rows, self.cols)]
        )
        image_xy = fine.image_xy + upsample_field(delta, self.rows, self.cols, (rows, cols))
        meta = {
            **fine.meta,
            "iterations": its,
            "salient_vertex_fraction": frac,
            "refine_grid": str(self.coarse_grid),
        }
        warp = Warp(
            fine.grid_uv, image_xy, fine.content_size, fine.projector, meta, depth=fine.depth
        )
        folds = fold_count(warp)
        if folds:
            log.warning("content-aware refinement folds %d triangles; showing content-free", folds)
            return Warp(fine.grid_uv, fine.image_xy, fine.content_size, fine.projector,
                        {**fine.meta, "refine_folds": folds}, depth=fine.depth)  # fmt: skip
        return warp
