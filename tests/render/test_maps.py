"""Per-pixel maps: weights computed once per pose serve every later warp of it."""

from __future__ import annotations

import numpy as np

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.render.maps import PixelWeights, map_from_warp
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid


def test_weights_of_a_pose_map_any_warp_of_it() -> None:
    surface = simulate_surface("sphere-convex", step=4)
    settings = WarpSettings(mode="conformal", grid=Grid(12, 8))
    free = compute_warp(surface, (320, 200), settings=settings)
    weights = PixelWeights.build(free.grid_uv, free.depth, free.projector, surface)
    cmap = np.zeros((20, 32), np.float32)
    cmap[5:15, 4:12] = 1.0
    aware = compute_warp(surface, (320, 200), cmap, WarpSettings(grid=Grid(12, 8)))
    assert aware.meta["iterations"] > 0
    for warp in (free, aware):  # map_from_warp is PixelWeights.map: the same code, exact
        np.testing.assert_array_equal(
            weights.map(warp.image_xy, warp.content_size), map_from_warp(warp, surface)
        )


def test_pixels_without_surface_under_their_triangle_show_black() -> None:
    surface = simulate_surface("sphere-convex", step=4)
    warp = compute_warp(surface, (320, 200), settings=WarpSettings(mode="conformal"))
    m = map_from_warp(warp, surface)
    assert np.isnan(m[0, 0]).all() and np.isnan(m[-1, -1]).all()
    shown = np.isfinite(m).all(axis=2)
    inside = shown & (m[..., 0] >= -0.5) & (m[..., 0] <= 319.5)
    inside &= (m[..., 1] >= -0.5) & (m[..., 1] <= 199.5)
    # past the content's border only the ring next to it (the renderer's black edge)
    ring = np.zeros_like(inside)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            ring |= np.roll(np.roll(inside, dy, axis=0), dx, axis=1)
    assert inside.sum() > 0.3 * inside.size
    assert np.all(ring[shown])
