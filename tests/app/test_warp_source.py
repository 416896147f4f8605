"""The runtime's warp source: its pose cache serves a surface seen before, and a device
whose "up" moved while it stayed within an orientation bin of the same surface gets the
cached solve placed upright again, not a new solve."""

from __future__ import annotations

import numpy as np

from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.app.warps import PoseEntry, WarpSource
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.warp.engine import WarpSettings

SIZE = (640, 400)


def up(deg: float) -> tuple[float, float, float]:
    a = np.deg2rad(deg)
    return (float(np.sin(a)), float(-np.cos(a)), 0.0)


def test_another_up_in_front_of_the_same_surface_is_placed_not_solved() -> None:
    s = simulate_surface("cylinder-convex")
    settings = AppSettings()
    source = WarpSource(s.projector, settings, Telemetry(100))
    o = np.zeros(3)

    def pose(deg: float) -> tuple[PoseEntry, bool]:
        return source.pose(s, 5, 0, o, SIZE, WarpSettings(mode="content", up=up(deg)))

    first, hit = pose(0.0)
    assert not hit
    assert pose(0.0) == (first, True)  # the same pose: a cache hit
    turned, hit = pose(3.0)  # beyond up_match_rad: another "up"
    counters = source.telemetry.counters
    assert not hit and counters["re_placed"] == 1 and counters["content_free"] == 1
    assert turned is not first
    assert np.array_equal(turned.up, up(3.0))
    assert turned.weights is first.weights
    # what a fresh solve for that "up" would have shown
    fresh = source.planner.content_free(s, SIZE, WarpSettings(mode="content", up=up(3.0)))
    assert np.allclose(turned.warp.image_xy, fresh.warp.image_xy, atol=1e-9, equal_nan=True)
    assert pose(3.0) == (turned, True)  # filed under its own key
    # the device turned further than an orientation bin: the surface is solved again
    # (a turn the depth check can miss, e.g. about the axis of a column)
    rolled = np.array([0.0, 0.0, 2 * settings.orientation_bin_rad])
    _, hit = source.pose(s, 5, 0, rolled, SIZE, WarpSettings(mode="content", up=up(6.0)))
    assert not hit and counters["re_placed"] == 1 and counters["content_free"] == 2
    # without the cache every pose is solved
    off = WarpSource(s.projector, AppSettings(caching=False), Telemetry(100))
    off.pose(s, 5, 0, o, SIZE, WarpSettings(mode="content", up=up(0.0)))
    off.pose(s, 5, 0, o, SIZE, WarpSettings(mode="content", up=up(3.0)))
    assert off.telemetry.counters["re_placed"] == 0 and off.telemetry.counters["content_free"] == 2


def test_a_surface_turned_in_front_of_the_device_is_not_served_the_old_warp() -> None:
    """A wall turned 35 degrees away, the device turned 1.2 degrees (the "up" the same
    within its match): the depths still agree within the sensor's noise, but the warp
    made before would tip the content on it (1.8 degrees on a replayed hand); it is
    solved again, neither served nor re-placed."""
    from adaproj_edge.geometry.projector import Projector
    from adaproj_edge.geometry.rotations import rotation_matrix
    from adaproj_edge.geometry.surface import Surface
    from adaproj_edge.warp.posecache import surfaces_agree
    from adaproj_edge.warp.warpmap import Grid

    p = Projector.default()
    settings = AppSettings()
    rays = p.rays(Grid().vertices(p))
    rays = rays / rays[..., 2:3]
    yaw = np.radians(35.0)
    n = np.array([np.sin(yaw), 0.0, np.cos(yaw)]) / 1.5

    def wall(normal: np.ndarray) -> Surface:
        return Surface((rays / (rays @ normal)[..., None]).astype(np.float32), p)

    before, after = wall(n), wall(rotation_matrix(np.radians([1.2, 0.0, 0.0])) @ n)
    depth = [s.points[..., 2].astype(np.float64) for s in (before, after)]
    source = WarpSource(p, settings, Telemetry(100))
    assert surfaces_agree(depth[1], depth[0], (5, 5), source.sensor)  # the depth check passes
    o = np.zeros(3)
    warp = WarpSettings(mode="content", up=up(0.0))
    first, hit = source.pose(before, 5, 0, o, SIZE, warp)
    assert not hit and source.pose(before, 5, 0, o, SIZE, warp) == (first, True)
    again, hit = source.pose(after, 5, 0, o, SIZE, warp)
    counters = source.telemetry.counters
    assert not hit and again is not first
    assert counters["content_free"] == 2 and counters.get("re_placed", 0) == 0
