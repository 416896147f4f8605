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
