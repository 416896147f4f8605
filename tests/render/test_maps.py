"""Per-pixel maps: weights computed once per pose serve every later warp of it."""

from __future__ import annotations

import numpy as np

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.projector import Projector
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


def test_pixels_on_the_outline_of_the_mesh_are_shown() -> None:
    """A pixel on a grid line or cell diagonal that bounds a triangle with surface shows
    that triangle, also when the triangle on its other side (where the layout puts it)
    has none: the outline's last column of pixels carried content the placement counts
    on (issue 13: a cylinder's silhouette meeting the picture's corner lost 132 px)."""
    proj = Projector.default()
    grid = Grid(4, 4)
    uv = grid.vertices(proj)
    depth = np.ones(uv.shape[:2])
    depth[:, 4] = np.nan  # the last column of cells has no surface
    depth[0, 2] = np.nan  # cell (0, 1): upper triangle (a, b, e) without, lower with
    w = PixelWeights.build(uv, depth, proj)
    # the identity warp: every shown pixel maps to itself (a plane at depth 1)
    m = w.map(uv, (proj.width, proj.height), clip=False)
    # ground truth: inside or on a closed triangle whose three corners have surface
    yy, xx = np.mgrid[0 : proj.height, 0 : proj.width].astype(float)
    expect = np.zeros(xx.shape, dtype=bool)
    for r in range(4):
        for c in range(4):
            a, b, d, e = (r, c), (r, c + 1), (r + 1, c), (r + 1, c + 1)
            for tri in ((a, b, e), (a, e, d)):
                if not all(np.isfinite(depth[v]) for v in tri):
                    continue
                p = [uv[v] for v in tri]
                side = [
                    (q[0] - o[0]) * (yy - o[1]) - (q[1] - o[1]) * (xx - o[0])
                    for o, q in ((p[0], p[1]), (p[1], p[2]), (p[2], p[0]))
                ]
                expect |= (side[0] >= 0) & (side[1] >= 0) & (side[2] >= 0)
    shown = np.isfinite(m).all(axis=2)
    np.testing.assert_array_equal(shown, expect)
    assert shown[int(uv[1, 0, 1]) :, int(uv[0, 3, 0])].all()  # the outline's column
    np.testing.assert_allclose(m[shown], np.stack([xx, yy], -1)[shown], atol=1e-3)
