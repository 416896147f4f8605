"""The warp pipeline of the runtime: surface -> content-free warp (cached per pose) ->
content-aware refinement (warm-started) -> display maps.

Built from the engine's pieces (:mod:`adaproj_edge.warp.engine`), so the runtime can
keep the solver's positions between updates: the content-aware alternation starts
from the previous solution when the mesh is the same, else from the content-free
warp. Display maps are built by perspective-correct interpolation of the mesh at a
reduced resolution (``map_scale``) and scaled up: the per-pixel surface map of
:func:`~adaproj_edge.render.maps.map_from_warp` costs about a second on the board.

Stage times are measured with ``time.perf_counter`` and only reported; no decision
depends on them.
"""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.app.posecache import CachedWarp
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.projector import FloatArray, Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.frame import RemapMaps
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.warp.engine import FAST, WarpSettings, make_warp, refine, standard_warp
from adaproj_edge.warp.mesh import Grid, Warp
from adaproj_edge.warp.meshgeom import MeshGeometry, WarpCache
from adaproj_edge.warp.placement import Placement, place


@dataclass
class StageTimes:
    """Wall-clock seconds per stage, for the summary and the benchmark."""

    samples: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))

    def add(self, stage: str, seconds: float) -> None:
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
    small = scaled_projector(p, factor)
    grid_uv = (warp.grid_uv + 0.5) / factor - 0.5
    coarse = Warp(grid_uv, warp.image_xy, warp.content_size, small, warp.meta, depth=warp.depth)
    m = map_from_warp(coarse)
    # align pixel centres: full-res pixel x sits at (x + 0.5) / factor - 0.5 coarse
    big = cv2.resize(m, (p.width, p.height), interpolation=cv2.INTER_LINEAR)
    return np.asarray(big, dtype=np.float32)


@dataclass
class Solution:
    """A content-aware result kept for the next warm start."""

    warp: Warp
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
    """

    def __init__(
        self,
        projector: Projector,
        grid: Grid | None = None,
        map_scale: int = 4,
        warm_start: bool = True,
        caching: bool = True,
    ) -> None:
        self.projector = projector
        self.grid = grid or Grid()
        self.map_scale = map_scale
        self.warm_start = warm_start
        self.warm_rel = 0.01  # a solution warm-starts surfaces within 1 % depth
        self.warp_cache: WarpCache | None = WarpCache() if caching else None
        self.times = StageTimes()
        self.last: Solution | None = None
        self.iterations: list[int] = []

    def timer(self, stage: str) -> _Timer:
        return _Timer(self.times, stage)

    def maps(self, warp: Warp) -> tuple[NDArray[np.float32], RemapMaps]:
        with self.timer("map"):
            m = display_map(warp, self.map_scale)
            return m, RemapMaps.from_map(m)

    def plain(self, content_size: tuple[int, int]) -> tuple[Warp, RemapMaps]:
        """The content letterboxed on the frame (no pre-warp)."""
        surface = Surface(np.ones((2, 2, 3), np.float32), self.projector)
        warp = standard_warp(surface, content_size, self.grid)
        return warp, self.maps(warp)[1]

    def content_free(
        self, surface: Surface, content_size: tuple[int, int], settings: WarpSettings
    ) -> CachedWarp:
        """E' = E_a + lambda E_r for ``surface`` (paper eq. 7), with its display maps."""
        with self.timer("content_free"):
            surface.check_usable()
            mesh = MeshGeometry.build(surface, self.grid, self.warp_cache)
            v_conf = FAST.conformal(mesh)
            v, _ = FAST.content_free(mesh, v_conf, settings.lam)
            placement = place(mesh, v, content_size, settings.up)
            warp = make_warp(mesh, v, placement, surface, content_size, settings, 0, 0.0, {})
        _, maps = self.maps(warp)
        depth = surface.points[..., 2].astype(np.float64)
        return CachedWarp(warp, maps, depth, v, placement, mesh.verts.copy())

    def content_aware(
        self,
        surface: Surface,
        content_map: ContentMap,
        settings: WarpSettings,
        start: CachedWarp,
    ) -> tuple[Warp, NDArray[np.float32], RemapMaps]:
        """The content-aware alternation from a warm start: the last solution when it
        was made for (nearly) this surface, else the content-free warp ``start`` (when
        it belongs to this mesh), else the content-free warp solved afresh."""
        with self.timer("content_aware"):
            mesh = MeshGeometry.build(surface, self.grid, self.warp_cache)
            depth = surface.points[..., 2].astype(np.float64)
            last = self.last
            if (
                self.warm_start
                and last is not None
                and np.array_equal(last.verts, mesh.verts)
                and last.start.matches(depth, self.warm_rel, 0.97)
            ):
                # near the answer already: a few steps are enough
                v, placement = last.v, last.placement
                settings = replace(settings, max_iterations=min(settings.max_iterations, 4))
            elif np.array_equal(start.verts, mesh.verts):
                v, placement = start.v, start.placement
            else:
                v, _ = FAST.content_free(mesh, FAST.conformal(mesh), settings.lam)
                placement = place(mesh, v, content_map.content_size, settings.up)
            v, placement, its, frac = refine(mesh, v, placement, content_map, settings, FAST)
            warp = make_warp(
                mesh, v, placement, surface, content_map.content_size, settings, its, frac, {}
            )
            self.iterations.append(its)
            start_now = replace(start, depth=depth)
            self.last = Solution(warp, v, placement, mesh.verts.copy(), its, start_now)
        map_xy, maps = self.maps(warp)
        return warp, map_xy, maps
