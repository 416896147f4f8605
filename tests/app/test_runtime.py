"""The runtime's parts: gestures, motion hysteresis, pose cache, faults, link content."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import cv2
import numpy as np
import pytest

from adaproj_edge.app.content import Item, builtin_item, mask_content_map
from adaproj_edge.app.inputs import SourceFault, feed
from adaproj_edge.app.runtime import Runtime, State
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.errors import ImageError, WarpError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.link.device import Content, Settings
from adaproj_edge.motion.tracker import MotionTracker
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate
from tests.app.records import feed_records

CAL = Calibration.default()
MS = 1_000_000


def _runtime(items: list[Item] | None = None) -> tuple[Runtime, VirtualClock, MemoryDisplay]:
    clock = VirtualClock(1_000 * MS)
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    rt = Runtime(CAL, display, clock, items or [builtin_item()], content_map_fn=mask_content_map)
    rt.boot()
    return rt, clock, display


def _second_item() -> Item:
    img = np.full((300, 400, 3), 200, np.uint8)
    return Item("grey", img, mask_content_map("grey", img, None, 0.5))


def _press(rt: Runtime, clock: VirtualClock, t_ms: int, held_ms: int = 100) -> None:
    for dt, pressed in ((0, True), (held_ms, False)):
        clock.advance_to((t_ms + dt) * MS)
        rt.tick()
        rt.on_button(ButtonEvent(clock.now_ns(), clock.now_ns(), 28, pressed))


def test_boot_shows_the_content_plainly_and_waits() -> None:
    rt, _, display = _runtime()
    assert rt.state == State.IDLE
    assert display.count == 1 and display.last is not None and display.last.mean() > 10


def test_gestures_double_press_long_press_and_press() -> None:
    rt, clock, _ = _runtime([builtin_item(), _second_item()])
    _press(rt, clock, 2000)
    _press(rt, clock, 2200)  # second press 100 ms after the first release: double
    clock.advance_to(3000 * MS)
    rt.tick()
    assert rt.item.name == "grey" and rt.state == State.IDLE
    _press(rt, clock, 4000, held_ms=1000)  # long
    assert rt.plain
    _press(rt, clock, 6000)  # single: acted on once the double-press window is over
    assert rt.state == State.IDLE
    clock.advance_to(6500 * MS)
    rt.tick()
    assert rt.state == State.CAPTURING
    kinds = [e["kind"] for e in rt.telemetry.events if e["event"] == "gesture"]
    assert kinds == ["double", "long", "press"]


def _samples(gyro: float, t0_s: float, seconds: float) -> list[ImuSample]:
    out = []
    for k in range(int(seconds * 208)):
        t = int((t0_s + k / 208) * 1e9)
        out.append(ImuSample(t, t, (0.0, -9.81, 0.0), (gyro, 0.0, 0.0)))
    return out


def test_motion_starts_at_once_and_settles_with_hysteresis() -> None:
    m = MotionTracker(CAL.R_P_I)
    changes = [(s.sensor_ns, m.update(s)) for s in _samples(0.0, 0.0, 0.5)]
    assert all(c is None for _, c in changes)
    moving = [(t, c) for t, c in ((s.sensor_ns, m.update(s)) for s in _samples(0.5, 0.5, 0.3)) if c]
    assert len(moving) == 1 and moving[0][0] < 0.6e9
    settled = [
        (t, c)
        for t, c in ((s.sensor_ns, m.update(s)) for s in _samples(0.0, 0.8, 1.0))
        if c is not None
    ]
    assert len(settled) == 1 and settled[0][1] is False
    assert settled[0][0] >= 0.8e9 + 0.3e9  # not before settle_s of stillness
    assert abs(m.orientation_vector()[0]) > 0.1  # the turn was integrated


@pytest.fixture(scope="module")
def still_records() -> list[object]:
    hand = HandMotion(2.6, seed=4, move_m=0.0, move_rad=0.0)
    settings = SimulationSettings(seconds=2.6, depth_fps=10.0, seed=4, presses=(0.1,), motion=hand)
    return list(simulate(Scene.load("cylinder-convex"), CAL, settings))


def test_a_still_hand_gives_a_still_image(still_records: list[object]) -> None:
    rt, clock, _display = _runtime()
    feed_records(rt, clock, still_records)
    assert rt.state == State.PROJECTING
    assert not [e for e in rt.telemetry.events if e["event"] == "moving"]
    # the capture, then at most one re-warp as the average of more frames settles
    assert 1 <= len(rt.telemetry.updates) <= 2, rt.telemetry.updates
    assert rt.counters["estimates"] >= 8


def test_the_history_the_runtime_keeps_is_bounded(still_records: list[object]) -> None:
    # the device runs for days: events, updates and stage times keep the latest only
    clock = VirtualClock(1_000 * MS)
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    settings = AppSettings(history=3, refine_at_frames=(3, 4, 5, 6, 7, 8))
    rt = Runtime(CAL, display, clock, [builtin_item()], settings, mask_content_map)
    rt.boot()
    feed_records(rt, clock, still_records)
    assert rt.telemetry.update_count > 3 and len(rt.telemetry.updates) == 3
    assert len(rt.telemetry.events) <= 3 and len(rt.telemetry.states) <= 3
    assert all(len(v) <= 3 for v in rt.telemetry.times.samples.values())
    assert rt.telemetry.times.summary()["render"]["n"] == 3


def test_once_settled_the_refinement_builds_on_an_averaged_content_free_warp() -> None:
    # still 1 s, move 0.8 s, still again: the refinement after the move waits for 3
    # averaged frames, makes their content-free warp on one depth frame (nothing
    # shown), and refines on it, from the pose cache, on the next
    hand = HandMotion(3.2, seed=3, still_s=1.0, move_s=0.8)
    settings = SimulationSettings(seconds=3.2, depth_fps=15.0, seed=3, presses=(0.1,), motion=hand)
    rt, clock, _ = _runtime()
    feed_records(rt, clock, list(simulate(Scene.load("cylinder-convex"), CAL, settings)))
    settled = [e["t_ns"] for e in rt.telemetry.events if e["event"] == "settled"]
    assert settled
    after = [u for u in rt.telemetry.updates if u["t_ns"] > settled[-1]]
    assert after and after[0]["reason"] == "settled"
    assert after[0]["kind"] == "content-aware" and after[0]["cache_hit"] is True
    assert rt.telemetry.times.summary()["prepare"]["n"] >= 1
    # the first settled frame is about 4 depth frames (at 15 a second) after settling
    assert 3 * MS * 66 <= after[0]["t_ns"] - settled[-1] <= 6 * MS * 67


def test_faults_keep_the_frame_mark_it_and_clear(still_records: list[object]) -> None:
    rt, clock, display = _runtime()
    feed_records(rt, clock, still_records)
    good = display.last.copy()  # type: ignore[union-attr]
    feed(rt, SourceFault("imu", "IMU read failed"))
    feed(rt, SourceFault("depth", "the OAK-D stopped sending depth"))
    marked = display.last
    assert marked is not None and set(rt.faults.active) == {"imu", "camera"}
    differs = np.any(marked != good, axis=2)
    ys, xs = np.nonzero(differs)
    assert ys.max() < 30 and xs.min() > CAL.projector.width - 60  # only the small mark
    frames = [r for r in still_records if isinstance(r, DepthFrame)]
    imu = [r for r in still_records if isinstance(r, ImuSample)]
    clock.advance_to(clock.now_ns() + 100 * MS)
    rt.on_imu(replace(imu[-1], sensor_ns=clock.now_ns(), receive_ns=clock.now_ns()))
    rt.on_depth(replace(frames[-1], receive_ns=clock.now_ns()))
    assert rt.faults.active == {} and np.array_equal(display.last, good)
    assert rt.status()["state"] == "projecting"


def test_a_depth_dropout_is_a_fault_not_a_crash(still_records: list[object]) -> None:
    rt, clock, _display = _runtime()
    feed_records(rt, clock, still_records)
    frame = next(r for r in still_records if isinstance(r, DepthFrame))
    clock.advance_to(clock.now_ns() + 300 * MS)
    rt.on_depth(replace(frame, depth_mm=np.zeros_like(frame.depth_mm), receive_ns=clock.now_ns()))
    assert "depth" in rt.faults
    far = frame.depth_mm.copy()
    far[far > 0] = 9000
    clock.advance_to(clock.now_ns() + 300 * MS)
    rt.on_depth(replace(frame, depth_mm=far, receive_ns=clock.now_ns()))
    assert "range" in rt.faults


def test_content_from_the_link_is_shown_without_a_restart(tmp_path: Path) -> None:
    rt, _clock, display = _runtime()
    img = np.zeros((200, 300, 3), np.uint8)
    img[:, :150] = (0, 0, 255)
    cv2.imwrite(str(tmp_path / "red.png"), img)
    cv2.imwrite(str(tmp_path / "mask.png"), np.full((200, 300), 255, np.uint8))
    cv2.imwrite(str(tmp_path / "small.png"), np.zeros((10, 10), np.uint8))
    rt.activate(Content(tmp_path / "red.png", tmp_path / "mask.png", Settings("content", 0.6)))
    shown = display.count
    rt.tick()  # the runtime's own thread takes it up
    assert rt.item.name == "red.png" and display.count == shown + 1
    assert rt.status()["image"] == "red.png" and rt.status()["settings"]["threshold"] == 0.6
    png = cv2.imdecode(np.frombuffer(rt.frame_png(), np.uint8), cv2.IMREAD_COLOR)
    assert png.shape == (CAL.projector.height, CAL.projector.width, 3)
    with pytest.raises(ImageError):
        rt.activate(Content(tmp_path / "red.png", tmp_path / "small.png"))
    assert rt.status()["errors"]
    # a mask of another size but the content's aspect is fitted (as the CLI does)
    half = np.zeros((100, 150), np.uint8)
    half[:, :75] = 255
    cv2.imwrite(str(tmp_path / "half.png"), half)
    rt.activate(Content(tmp_path / "red.png", tmp_path / "half.png"))
    rt.tick()
    cmap = rt.item.content_map
    assert cmap is not None and cmap.values.shape == (200, 300)
    assert cmap.values[:, :140].min() == 1.0 and cmap.values[:, 160:].max() == 0.0


def test_a_device_that_fails_is_reported_and_opened_again() -> None:
    import queue
    import threading

    from adaproj_edge.app.live import _pump, _Source
    from adaproj_edge.errors import DeviceError

    opened: list[int] = []

    def open_depth() -> Callable[[], object]:
        opened.append(1)
        if len(opened) == 1:
            raise DeviceError("the OAK-D is not there")
        return lambda: "frame"

    out: queue.Queue[object] = queue.Queue()
    stop = threading.Event()
    clock = VirtualClock()
    t = threading.Thread(target=_pump, args=(_Source("depth", open_depth), out, stop, clock, 1.0))
    t.start()
    first, second = out.get(timeout=5), out.get(timeout=5)
    stop.set()
    t.join(timeout=5)
    assert first == SourceFault("depth", "the OAK-D is not there")
    assert second == "frame" and clock.now_ns() >= 1_000_000_000


def test_run_without_the_hardware_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    if Path("/sys/class/graphics/fb0").exists():
        pytest.skip("a framebuffer is attached")
    from adaproj_edge.cli import main

    assert main(["run", "--board", "rpi5-oakd"]) == 2
    assert "framebuffer" in capsys.readouterr().err


def test_boot_shows_the_last_good_warp(still_records: list[object], tmp_path: Path) -> None:
    clock = VirtualClock(1_000 * MS)
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    rt = Runtime(CAL, display, clock, [builtin_item()], state_dir=tmp_path)
    rt.boot()
    feed_records(rt, clock, still_records)
    assert (tmp_path / "last-warp.npz").exists()
    kinds: list[str] = []
    again = Runtime(
        CAL,
        MemoryDisplay(CAL.projector.width, CAL.projector.height),
        VirtualClock(),
        [builtin_item()],
        on_frame=lambda t, f, info: kinds.append(info["kind"]),
        state_dir=tmp_path,
    )
    again.boot()
    assert kinds == ["last-warp"] and again.state == State.IDLE
    other = Runtime(CAL, MemoryDisplay(), VirtualClock(), [_second_item()], state_dir=tmp_path)
    other.boot()  # another content size: plainly
    assert other.shown_warp is not None and other.shown_warp.meta["mode"] == "standard"


def _last_warp_variants() -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """Well-formed warp files (right keys and dtypes) with shapes that do not fit."""
    item = builtin_item()
    rt = Runtime(
        CAL, MemoryDisplay(CAL.projector.width, CAL.projector.height), VirtualClock(), [item]
    )
    warp, _ = rt.warps.plain(item.size)
    meta = {
        "mode": "standard",
        "content_width": item.size[0],
        "content_height": item.size[1],
        "width": CAL.projector.width,
        "height": CAL.projector.height,
    }
    base = {"grid_uv": warp.grid_uv, "image_xy": warp.image_xy, "K": CAL.projector.K}
    r, c = warp.grid_uv.shape[:2]
    return {
        "grid 1x1": {**base, "grid_uv": warp.grid_uv[:1, :1], "image_xy": warp.image_xy[:1, :1]},
        "grid 0x0": {**base, "grid_uv": np.zeros((0, 0, 2)), "image_xy": np.zeros((0, 0, 2))},
        "depth of another grid": {**base, "depth": np.ones((r + 1, c))},
        "map of another frame": {**base, "map_xy": np.zeros((10, 10, 2), np.float32)},
        "grid not over the frame": {**base, "grid_uv": warp.grid_uv * 0.5},
        "infinite content": {**base, "image_xy": np.full_like(warp.image_xy, np.inf)},
        "frame of 1e9 pixels": {**base, "meta": {**meta, "width": 1e9}},
        "content width -3": {**base, "meta": {**meta, "content_width": -3}},
    }, meta


LAST_WARPS, LAST_META = _last_warp_variants()


@pytest.mark.parametrize("case", list(LAST_WARPS))
def test_a_last_warp_that_does_not_fit_is_ignored_at_boot(
    case: str, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    arrays = dict(LAST_WARPS[case])
    meta = arrays.pop("meta", LAST_META)
    np.savez(tmp_path / "last-warp.npz", meta=np.array(json.dumps(meta)), **arrays)
    kinds: list[str] = []
    rt = Runtime(
        CAL,
        MemoryDisplay(CAL.projector.width, CAL.projector.height),
        VirtualClock(),
        [builtin_item()],
        on_frame=lambda t, f, info: kinds.append(info["kind"]),
        state_dir=tmp_path,
    )
    rt.boot()
    assert rt.state == State.IDLE and "last-warp" not in kinds
    assert any("ignoring the last warp" in r.getMessage() for r in caplog.records)


def test_what_is_made_ahead_of_a_refinement_may_fail_without_a_fault(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A settled device makes its first refinement's conformal pieces in the frame that
    shows nothing (``PoseEntry.prepare``); that is only made ahead: a failure there is
    logged, raised to no one (the refinement makes them, or meets the failure, itself)."""
    rt, _, _ = _runtime()
    calls: list[object] = []

    class Entry:
        def prepare(self, content_map: object, up: object) -> None:
            calls.append(content_map)
            raise WarpError("made ahead to fail")

    monkeypatch.setattr(rt.surfaces, "prepared", lambda est: None)
    monkeypatch.setattr(rt, "_pose", lambda surface, frames, refine: (Entry(), False))
    monkeypatch.setattr(rt, "_content_map", lambda: object())
    rt.plain = False
    assert rt.item.settings.mode == "content"
    est = SimpleNamespace(frames=3)  # an averaged estimate, as far as _prepare reads it
    with caplog.at_level("INFO", logger="adaproj_edge.app.runtime"):
        rt._prepare(est)  # type: ignore[arg-type]
    assert len(calls) == 1 and "made ahead to fail" in caplog.text
    rt.plain = True  # nothing refines: nothing is made ahead
    rt._prepare(est)  # type: ignore[arg-type]
    assert len(calls) == 1
