"""The tap-then-hold gesture: the surface's colour measured again on its own. The
gesture itself; the captures on the calibration simulator's devices (a painted wall
corner: the measurement through the calibration's geometry finds the paint); bad
captures refused with the reason and nothing written; the runtime uses a new
measurement and keeps the old one on a refusal."""

from __future__ import annotations

import queue
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.app.calibration_run import measure_colour_on
from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.gestures import Gestures
from adaproj_edge.app.live import Device, _measure_colour, _Readers
from adaproj_edge.app.runtime import Runtime, State
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.procam.procedure import LiveShow
from adaproj_edge.render.reflectance import Response
from adaproj_edge.session.calibration_sim import CalibrationSimSettings, SimFaults, sim_rig
from adaproj_edge.session.simulator import Scene
from tests.commands.test_simulate_calibration_colour import albedo_png, assert_paint_measured

CAL = Calibration.default()
MS = 1_000_000


def _edge(t_ms: int, pressed: bool) -> ButtonEvent:
    return ButtonEvent(t_ms * MS, t_ms * MS, 28, pressed)


def test_a_tap_then_a_hold_asks_for_the_colour_and_the_other_gestures_stay() -> None:
    g = Gestures(0.35, 0.8, 5.0)
    g.on_button(_edge(1000, True))
    assert g.on_button(_edge(1100, False)) is None
    assert g.on_button(_edge(1300, True)) is None  # within the double-press window
    assert g.tick(6299 * MS) is None
    assert g.tick(6300 * MS) == "colour"
    assert g.on_button(_edge(7000, False)) is None and g.tick(8000 * MS) is None
    # a hold alone still calibrates; a tap then a long press is still a tap-hold; a
    # tap and a hold begun after the window is a press, then a hold
    g.on_button(_edge(10000, True))
    assert g.tick(15000 * MS) == "hold"
    g.on_button(_edge(15500, False))
    g.on_button(_edge(20000, True))
    g.on_button(_edge(20100, False))
    g.on_button(_edge(20300, True))
    assert g.on_button(_edge(21300, False)) == "tap_hold"
    g.on_button(_edge(30000, True))
    g.on_button(_edge(30100, False))
    assert g.tick(30500 * MS) == "press"
    g.on_button(_edge(30600, True))
    assert g.tick(35600 * MS) == "hold"


class _Console:
    def __init__(self) -> None:
        self.said: list[str] = []

    def say(self, event: str, message: str) -> None:
        self.said.append(message)

    def record(self, rec: object) -> None:
        pass


def _measure(tmp_path: Path, faults: SimFaults | None = None, move: bool = False):  # type: ignore[no-untyped-def]
    albedo = albedo_png(tmp_path / "albedo.png")
    cam = replace(Board.load("rpi5-oakd").camera, width=256, height=160)
    settings = CalibrationSimSettings(
        poses=1, seed=3, camera=cam, albedo=albedo.astype(np.float32), faults=faults or SimFaults()
    )
    sim = sim_rig(Scene.load("corner"), CAL, settings)
    if move:  # the user steps 5 cm towards the wall in 0.2 s during the captures
        sim.world.path = replace(sim.world.path, move_s=0.2)
        here = sim.world.path.current().copy()
        sim.world.path.moves.append((0.4, here, here + np.r_[0, 0, 0.05, 0, 0, 0]))
    console = _Console()
    out = tmp_path / "unit.photometric.npz"
    clock = sim.world.clock
    t0 = clock.now_ns()
    show = LiveShow(sim.display, clock, console)
    rig = type("Rig", (), {"camera": sim.camera, "depth": sim.depth})()
    measured, message = measure_colour_on(
        show, rig, clock, Board.load("rpi5-oakd"), CAL, out, console
    )  # type: ignore[arg-type]
    return measured, message, out, albedo, (clock.now_ns() - t0) * 1e-9, console


def test_the_colour_captures_measure_the_painted_corner(tmp_path: Path) -> None:
    measured, message, out, albedo, seconds, console = _measure(tmp_path)
    assert measured is not None and "measured" in message and console.said == [message]
    # five frames and the depth before and after: under 3 s of the device's time
    assert seconds < 3.0
    # the paint found through the calibration's geometry (no Gray code), as tightly as
    # the Gray-code measurement finds it (the same checks and tolerances)
    assert_paint_measured(measured.response, albedo)
    back = Measured.load(out)  # written whole
    assert np.array_equal(back.response.mix, measured.response.mix)
    dist = back.distance_m[back.response.valid]
    assert 1.2 < dist.min() and dist.max() < 2.2  # the corner, 1.3-1.9 m away


@pytest.mark.parametrize(
    ("faults", "move", "reason"),
    [
        (SimFaults(exposure_scale=6.0), False, "saturated"),
        (SimFaults(projector_off=True), False, "barely brighter"),
        (None, True, "hold it still"),
    ],
)
def test_a_bad_capture_is_refused_with_its_reason_and_nothing_written(
    tmp_path: Path, faults: SimFaults | None, move: bool, reason: str
) -> None:
    measured, message, out, _, _, console = _measure(tmp_path, faults, move)
    assert measured is None and reason in message, message
    assert message.startswith("the surface's colour was not measured")
    assert console.said == [message]  # shown on the projector
    assert not out.exists() and not list(tmp_path.glob("*.tmp*"))


def _runtime(clock: VirtualClock) -> Runtime:
    display = MemoryDisplay(CAL.projector.width, CAL.projector.height)
    rt = Runtime(CAL, display, clock, [builtin_item()], None, mask_content_map)
    rt.boot()
    return rt


def _measured(level: float) -> Measured:
    w, h = CAL.projector.width // 2, CAL.projector.height // 2
    mix = np.broadcast_to(np.eye(3, dtype=np.float32) * level, (h, w, 3, 3)).copy()
    response = Response(mix, np.zeros((h, w, 3), np.float32), np.ones((h, w), bool))
    return Measured(response, np.full((h, w), 1.5), (CAL.projector.width, CAL.projector.height))


def test_the_device_loop_measures_and_the_runtime_uses_it_or_keeps_the_old() -> None:
    clock = VirtualClock(1_000 * MS)
    rt = _runtime(clock)
    old, new = _measured(50.0), _measured(80.0)
    rt.warps.measured = old
    rt.on_button(_edge(1000, True))
    rt.on_button(_edge(1100, False))
    rt.on_button(_edge(1300, True))
    clock.advance_to(6400 * MS)
    rt.tick()
    assert rt.colour_wanted and not rt.calibration_wanted
    answers: list[tuple[Measured | None, str]] = [
        (None, "the surface's colour was not measured: x")
    ]
    answers.append((new, "the surface's colour and the room's light measured"))
    server = Server(ContentStore(Path("/nonexistent")), rt)
    device = Device(rt, server, None, [], clock, measure_colour=lambda: answers.pop(0))
    readers = _Readers(device, queue.Queue(), 1.0)
    _measure_colour(device, readers)  # refused: the old measurement stays
    assert not rt.colour_wanted and rt.warps.measured is old and rt.state == State.IDLE
    rt.colour_wanted = True
    _measure_colour(device, readers)
    assert rt.warps.measured is new and rt.state == State.IDLE
    events = [e for e in rt.telemetry.events if e["event"] == "colour_measured"]
    assert [e["changed"] for e in events] == [False, True]
    kinds = [e["kind"] for e in rt.telemetry.events if e["event"] == "gesture"]
    assert kinds == ["colour"]
    # without a camera the gesture is answered
    rt.colour_wanted = True
    _measure_colour(Device(rt, server, None, [], clock), readers)
    assert not rt.colour_wanted and rt.warps.measured is new
    assert rt.telemetry.events[-1]["reason"] == "no camera on this device"
