"""The adaptive mesh kept in a :class:`~adaproj_edge.warp.mesh.WarpCache` with its surface.

A second warp of the same surface reuses the mesh (its crease unfolding and the guard's
display samples memoised on it) and gives the warp the uncached path gives; another
surface, or the same one seen by another projector, is another key. A mesh of the whole
grid lends the guard's display its crease unfolding instead of it being made again.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.seams import grid_unfolding
from adaproj_edge.warp.adaptive import adaptive_mesh, mesh_key
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import MeshGeometry, WarpCache
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid, Warp

CONTENT = (320, 200)
GRID = Grid(12, 12)
# the cached and the uncached path solve the same systems from the same mesh arrays: they
# differ by rounding at most, far below a content pixel; 1e-6 px is 1e-3 of the quality
# tests' finest figure (a developable surface exact to 3e-4 of a triangle's shape)
TOL = 1e-6


def _mask() -> np.ndarray:
    w, h = CONTENT
    yy, xx = np.mgrid[0:h, 0:w]
    inside = ((xx - 0.35 * w) / (0.15 * w)) ** 2 + ((yy - 0.5 * h) / (0.3 * h)) ** 2 <= 1
    return inside.astype(np.float32)


def _warp(surface: Surface, cache: WarpCache | None) -> Warp:
    return compute_warp(
        surface, CONTENT, _mask(), WarpSettings(mode="content", grid=GRID), cache=cache
    )


def _same(a: Warp, b: Warp) -> None:
    assert a.image_xy.shape == b.image_xy.shape
    assert np.array_equal(np.isnan(a.image_xy), np.isnan(b.image_xy))
    assert np.nanmax(np.abs(a.image_xy - b.image_xy)) <= TOL
    assert a.meta["guard"]["choice"] == b.meta["guard"]["choice"]
    assert a.meta.get("mesh") == b.meta.get("mesh")


def test_a_cached_mesh_gives_the_uncached_warp_and_another_surface_misses() -> None:
    # a curved crease (refined grid, unfolding, the guard's display samples) ...
    floor = simulate_surface("cylinder-floor", step=4)
    # ... and a straight one on the same lattice and projector
    corner = simulate_surface("corner", step=4)
    cache = WarpCache()
    first = _warp(floor, cache)
    assert (cache.mesh_hits, cache.mesh_misses) == (0, 1)
    again = _warp(floor, cache)
    assert (cache.mesh_hits, cache.mesh_misses) == (1, 1)
    _same(again, first)
    _same(again, _warp(floor, None))
    # another surface must not be given the first one's mesh
    other = _warp(corner, cache)
    assert cache.mesh_misses == 2
    _same(other, _warp(corner, None))


def test_the_mesh_key_follows_the_surface_and_the_projector() -> None:
    surface = simulate_surface("bowl", step=8)
    key = mesh_key(surface, GRID, True)
    assert mesh_key(simulate_surface("bowl", step=8), GRID, True) == key
    # one lattice node moved by a millimetre (a new depth frame) is another surface
    points = surface.points.copy()
    points[10, 20, 2] += 1e-3
    assert mesh_key(Surface(points, surface.projector), GRID, True) != key
    # the same points seen through another projector (a calibration changed)
    K = surface.projector.K.copy()
    K[0, 0] *= 1.01
    moved = Surface(surface.points, dataclasses.replace(surface.projector, K=K))
    assert mesh_key(moved, GRID, True) != key
    assert mesh_key(surface, Grid(13, 12), True) != key
    assert mesh_key(surface, GRID, False) != key


def test_the_display_samples_take_the_meshs_own_grid_unfolding() -> None:
    # a mesh that kept every grid triangle unfolded them from the corners and probes
    # the display's grid_unfolding samples: the guard's display samples take it
    surface = simulate_surface("cylinder-floor", step=4)
    mesh, _ = adaptive_mesh(surface, GRID)
    assert mesh.topology.rows.size == 2 * mesh.grid.rows * mesh.grid.cols
    kept = mesh.memo["grid unfolding"]
    depth = mesh.points[:, 2].reshape(mesh.grid_uv.shape[:2])
    made = grid_unfolding(mesh.grid_uv, depth, surface.projector, surface)
    assert made.folded.any()
    assert np.array_equal(kept.folded, made.folded) and np.array_equal(kept.ruled, made.ruled)
    # the same function of the same inputs (1e-12 m: rounding, were the order of a sum
    # to change)
    for field in ("points", "rotation", "origin", "softness"):
        a, b = getattr(kept, field), getattr(made, field)
        assert np.array_equal(np.isnan(a), np.isnan(b))
        assert np.nanmax(np.abs(a - b)) <= 1e-12, field
    # a mesh of part of the grid (a coarse mesh told where to look) keeps none
    part = MeshGeometry.build(
        surface, GRID, may_rule=np.zeros(2 * GRID.rows * GRID.cols, dtype=bool)
    )
    assert "grid unfolding" not in part.memo
