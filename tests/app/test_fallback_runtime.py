"""The runtime never goes dark: a surface the warp cannot be made on as measured is shown
down the warp chain (counted, with its step in the update), and one nothing can be made
on keeps the last good picture with a fault mark."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.runtime import Runtime, State
from adaproj_edge.geometry.analytic import Plane, ray_cast
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.estimate import SurfaceEstimate
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate
from adaproj_edge.warp.warpmap import Grid
from tests.app.records import feed_records

CAL = Calibration.default()
MS = 1_000_000
PITCH = np.deg2rad(50.0)
FLOOR = Plane("floor", (0.0, -float(np.cos(PITCH)), -float(np.sin(PITCH))), -1.2)


@pytest.fixture(scope="module")
def records() -> list[object]:
    hand = HandMotion(1.6, seed=4, move_m=0.0, move_rad=0.0)
    settings = SimulationSettings(seconds=1.6, depth_fps=10.0, seed=4, presses=(0.1,), motion=hand)
    return list(simulate(Scene.load("plane"), CAL, settings))


def _floor_nodes() -> np.ndarray:
    p = CAL.projector
    return ray_cast(FLOOR, np.zeros(3), p.rays(Grid().vertices(p)))


def _run(records: list[object], surface: Surface) -> tuple[Runtime, MemoryDisplay]:
    """The runtime fed ``records``, every surface it estimates replaced by ``surface``."""
    clock = VirtualClock(1_000 * MS)
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    rt = Runtime(CAL, display, clock, [builtin_item()], content_map_fn=mask_content_map)
    rt.boot()

    def prepared(est: SurfaceEstimate) -> Surface:
        return surface

    rt.surfaces.prepared = prepared  # type: ignore[method-assign]
    feed_records(rt, clock, records)
    return rt, display


def test_a_floor_with_a_flying_pixel_is_projected_repaired(
    records: list[object], caplog: pytest.LogCaptureFixture
) -> None:
    """It raised "the warp folds over" and nothing was projected. The step down is
    logged with its reason (once while it stays the same) and counted per update."""
    pts = _floor_nodes()
    pts[0, 1] *= 0.6  # a flying pixel on the border
    with caplog.at_level(logging.WARNING, logger="adaproj_edge.app.runtime"):
        rt, display = _run(records, Surface(pts.astype(np.float32), CAL.projector))
    logged = [r.getMessage() for r in caplog.records if "no content-free warp" in r.getMessage()]
    assert len(logged) == 1 and "folds over" in logged[0] and "showing repaired" in logged[0]
    assert rt.state == State.PROJECTING and "warp" not in rt.faults
    assert rt.telemetry.updates and all(u["step"] == "repaired" for u in rt.telemetry.updates)
    assert rt.counters["fallback_repaired"] == len(rt.telemetry.updates)
    assert rt.counters["fallback_last-good"] == 0
    assert display.last is not None and display.last.mean() > 10  # a picture is shown


def test_a_surface_nothing_can_be_made_on_keeps_the_last_picture(records: list[object]) -> None:
    pts = _floor_nodes()
    r, c = np.mgrid[0 : pts.shape[0], 0 : pts.shape[1]]
    pts[(r + c) % 2 == 1] = np.nan  # speckle: no triangle, no planar piece
    rt, display = _run(records, Surface(pts.astype(np.float32), CAL.projector))
    assert "warp" in rt.faults and rt.counters["fallback_last-good"] >= 1
    assert rt.output.warp is not None and rt.output.warp.meta["mode"] == "standard"
    assert display.last is not None and display.last.mean() > 10  # the boot picture stays
