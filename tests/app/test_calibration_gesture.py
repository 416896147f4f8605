"""The hold gesture: 5 s on the button calibrates the device. The runtime asks, the
device loop stops its readers (closing their devices), runs the calibration and gives
the result back; a replay answers that it has no devices."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.app.calibration_run import ProjectedConsole, calibrate_device
from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.gestures import Gestures
from adaproj_edge.app.live import Device, _Source, run_loop
from adaproj_edge.app.runtime import Runtime, State
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import MonotonicClock, VirtualClock
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.render.reflectance import Response
from adaproj_edge.render.sheet import text_page

CAL = Calibration.default()
MS = 1_000_000


def _edge(t_ms: int, pressed: bool) -> ButtonEvent:
    return ButtonEvent(t_ms * MS, t_ms * MS, 28, pressed)


def test_a_hold_is_reported_while_held_and_its_release_is_no_gesture() -> None:
    g = Gestures(0.35, 0.8, 5.0)
    assert g.on_button(_edge(1000, True)) is None
    assert g.tick(5999 * MS) is None
    assert g.tick(6000 * MS) == "hold"
    assert g.tick(6500 * MS) is None  # once
    assert g.on_button(_edge(7000, False)) is None
    assert g.tick(8000 * MS) is None  # no stray single press after it
    # the other gestures are unchanged: a 1 s press is long, a short one a press
    assert g.on_button(_edge(9000, True)) is None
    assert g.on_button(_edge(10000, False)) == "long"
    g.on_button(_edge(11000, True))
    assert g.on_button(_edge(11100, False)) is None
    assert g.tick(11500 * MS) == "press"


def test_a_hold_must_outlast_a_long_press() -> None:
    with pytest.raises(ValueError, match="outlast"):
        Gestures(0.35, 0.8, 0.5)


def _runtime(clock: VirtualClock | MonotonicClock, settings: AppSettings | None = None) -> Runtime:
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    rt = Runtime(CAL, display, clock, [builtin_item()], settings, mask_content_map)
    rt.boot()
    return rt


def test_recalibrate_swaps_the_calibration_and_refuses_another_projector() -> None:
    clock = VirtualClock(1_000 * MS)
    rt = _runtime(clock)
    rt.on_button(_edge(1000, True))
    clock.advance_to(6100 * MS)
    rt.tick()
    assert rt.calibration_wanted
    new = replace(CAL, R_P_I=np.eye(3)[[1, 0, 2]] * np.array([1.0, 1.0, -1.0]))
    # the surface's colour measured at start survives the new warp source
    w, h = CAL.projector.width // 2, CAL.projector.height // 2
    response = Response(
        np.zeros((h, w, 3, 3), np.float32), np.zeros((h, w, 3), np.float32), np.ones((h, w), bool)
    )
    measured = Measured(response, np.full((h, w), 1.5), (CAL.projector.width, CAL.projector.height))
    rt.warps.measured = measured
    old_warps = rt.warps
    rt.recalibrate(new, "good: 0.3 px RMS")
    assert not rt.calibration_wanted and rt.calibration is new and rt.state == State.IDLE
    assert rt.warps is not old_warps and rt.warps.measured is measured
    assert np.array_equal(rt.motion.R_P_I, new.R_P_I)
    events = [e for e in rt.telemetry.events if e["event"] == "calibrated"]
    assert events[-1]["changed"] is True and events[-1]["reason"] == "good: 0.3 px RMS"

    other = replace(CAL, projector=replace(CAL.projector, width=640, height=400))
    with pytest.raises(AdaprojError, match="640x400 projector"):
        rt.recalibrate(other, "good")
    assert rt.calibration is new and not rt.calibration_wanted


class _Counted:
    """A fake source: how often it was opened and closed, and whether it runs."""

    def __init__(self, read: Callable[[], object]) -> None:
        self.read, self.opened, self.closed = read, 0, 0

    def open(self) -> Callable[[], object]:
        self.opened += 1
        return self.read

    def close(self) -> None:
        self.closed += 1


def test_the_device_loop_hands_its_devices_to_the_calibration() -> None:
    clock = MonotonicClock()
    settings = AppSettings(long_press_s=0.1, calibrate_hold_s=0.3)
    rt = _runtime(clock, settings)
    edges = [True]

    def button() -> ButtonEvent | None:
        time.sleep(0.02)
        if not edges:
            return None
        t = clock.now_ns()
        return ButtonEvent(t, t, 28, edges.pop(0))  # pressed, never released

    def imu() -> ImuSample:
        time.sleep(0.005)
        t = clock.now_ns()
        return ImuSample(t, t, (0.0, -9.81, 0.0), (0.0, 0.0, 0.0))

    fake_button, fake_imu = _Counted(button), _Counted(imu)
    seen: dict[str, object] = {}
    new = replace(CAL, R_P_I=-np.eye(3)[[0, 2, 1]])
    done = threading.Event()

    def calibrate() -> tuple[Calibration | None, str]:
        # the readers were stopped and their devices closed before the calibration
        seen["closed"] = (fake_button.closed, fake_imu.closed)
        seen["open"] = (fake_button.opened, fake_imu.opened)
        done.set()
        return new, "good: 0.31 px RMS"

    sources = [
        _Source("button", fake_button.open, fake_button.close),  # type: ignore[arg-type]
        _Source("imu", fake_imu.open, fake_imu.close),  # type: ignore[arg-type]
    ]
    server = Server(ContentStore(Path("/nonexistent-store-not-opened")), rt)
    stop = threading.Event()
    device = Device(rt, server, None, sources, clock, None, calibrate)
    loop = threading.Thread(target=run_loop, args=(device, stop))
    loop.start()
    try:
        assert done.wait(10)
        deadline = time.monotonic() + 5
        while fake_imu.opened < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        stop.set()
        loop.join(10)
    assert not loop.is_alive()
    assert seen["closed"] == (1, 1) and seen["open"] == (1, 1)
    assert fake_imu.opened == 2 and fake_imu.closed == 2  # opened again, closed at the end
    assert rt.calibration is new and rt.state == State.IDLE
    assert [e["kind"] for e in rt.telemetry.events if e["event"] == "gesture"] == ["hold"]


def test_without_a_calibration_the_hold_is_answered_and_the_loop_goes_on() -> None:
    clock = VirtualClock(1_000 * MS)
    rt = _runtime(clock)
    rt.calibration_wanted = True
    from adaproj_edge.app.live import _calibrate, _Readers

    device = Device(rt, Server(ContentStore(Path("/nonexistent")), rt), None, [], clock)
    _calibrate(device, _Readers(device, __import__("queue").Queue(), 1.0))
    assert not rt.calibration_wanted and rt.calibration is CAL
    assert rt.telemetry.events[-1]["reason"] == "no calibration on this device"


def test_calibrating_without_the_devices_says_why_on_the_projector(tmp_path: Path) -> None:
    board = Board.load("rpi5-oakd")
    board = replace(board, imu=replace(board.imu, bus=250))  # no /dev/i2c-250 here
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    out = tmp_path / "cal.toml"
    cal, message = calibrate_device(board, display, VirtualClock(), CAL, out)
    assert cal is None and "i2c-250" in message
    assert not out.exists()
    assert display.last is not None and display.last.shape == (800, 1280, 3)
    assert display.last.max() == 255  # the reason is written on the projector


def test_the_console_shows_the_newest_lines_wrapped_to_the_frame() -> None:
    display = MemoryDisplay(320, 200)
    console = ProjectedConsole(display, (320, 200))
    for i in range(10):
        console.say("move", f"pose {i}: move closer to the wall and hold still")
    assert len(console.lines) == 6 and console.lines[-1].startswith("pose 9")
    assert display.last is not None and display.last.shape == (200, 320, 3)
    page = text_page(["a " * 200], (320, 200))
    lit_rows = np.flatnonzero(page.max(axis=(1, 2)) > 0)
    assert lit_rows.size > 0 and lit_rows.max() < 200  # wrapped, and still on the page
    assert np.array_equal(page[:, 300:], np.zeros_like(page[:, 300:]))  # inside the margin
