"""``adaproj calibrate``: the projector, depth camera and IMU from structured light."""

from __future__ import annotations

import argparse
import logging
import queue
import threading
from pathlib import Path
from typing import Any

from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.board import DEVICE_CALIBRATION, Board, calibration_in_use
from adaproj_edge.hal.camera import CameraSettings, OakRig
from adaproj_edge.hal.clock import Clock, MonotonicClock
from adaproj_edge.hal.display import FramebufferDisplay
from adaproj_edge.hal.imu import Imu, ImuSample
from adaproj_edge.hal.lsm6dsox import Lsm6dsox, open_i2c
from adaproj_edge.procam.outputs import calibrate
from adaproj_edge.procam.plan import PlanSettings
from adaproj_edge.procam.procedure import Devices, LiveShow, ProcedureSettings
from adaproj_edge.procam.session_devices import recorded_capture
from adaproj_edge.session import schemas
from adaproj_edge.session.calibration_sim import camera_attachment, capture_settings
from adaproj_edge.session.codec import Record
from adaproj_edge.session.writer import SessionWriter

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "calibrate",
        help="calibrate the projector, depth camera and IMU from structured light",
        description="Point the device at a scene with depth (a wall corner is ideal; a wall "
        "and the floor work) and follow the instructions: at each pose the projector shows "
        "Gray-code patterns, the depth-aligned camera captures them and the depth frame is "
        "kept; the command says when to move and how many poses are still needed. Writes "
        "the calibration (TOML) with a report beside it (OUT.report.json, OUT.report.png) "
        "and prints a one-line verdict; only a good or acceptable calibration is written, "
        "and never over a better one without --force. See docs/calibration.md.",
    )
    p.add_argument("--board", default="rpi5-oakd", help="board name or board TOML file")
    p.add_argument(
        "--out",
        type=Path,
        default=DEVICE_CALIBRATION,
        metavar="FILE.toml",
        help=f"calibration file to write (default {DEVICE_CALIBRATION}, which `adaproj run` "
        "uses when it exists)",
    )
    p.add_argument(
        "--replay",
        type=Path,
        default=None,
        metavar="SESSION.mcap",
        help="solve from a recorded calibration session instead of the device",
    )
    p.add_argument(
        "--record",
        type=Path,
        default=None,
        metavar="SESSION.mcap",
        help="record the calibration session (patterns, captures, depth, IMU)",
    )
    p.add_argument("--force", action="store_true", help="replace a better calibration file")
    p.add_argument(
        "--calibration",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="starting guess (default: the calibration `adaproj run` would use)",
    )
    p.add_argument("--max-poses", type=int, default=8, help="stop after this many poses")
    p.set_defaults(run=run)


class Console:
    """Tells the user what the procedure says (stdout); records into a session."""

    def __init__(self, writer: SessionWriter | None = None) -> None:
        self.writer = writer

    def say(self, event: str, message: str) -> None:
        print(message, flush=True)
        if self.writer is not None and event in ("captured", "done"):
            self.writer.flush()

    def record(self, rec: Record) -> None:
        if self.writer is not None:
            self.writer.write(rec)


class PolledImu:
    """The IMU read on a thread of its own (the chip keeps only its newest sample, and
    the procedure is busy with the camera between its reads)."""

    def __init__(self, imu: Lsm6dsox, rate_hz: float, clock: Clock) -> None:
        self._imu, self._clock = imu, clock
        self._period_ns = int(0.5e9 / rate_hz)
        self._queue: queue.Queue[ImuSample] = queue.Queue(maxsize=100_000)
        self._stop = threading.Event()
        self._error: str | None = None
        self._thread = threading.Thread(target=self._run, name="imu", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                s = self._imu.read()
                if s is None:
                    self._clock.sleep_until(self._clock.now_ns() + self._period_ns)
                else:
                    self._queue.put(s)
        except Exception as e:  # handed to the reader: the procedure reports it
            self._error = str(e)

    def read(self) -> ImuSample | None:
        if self._error is not None:
            raise CalibrationError(f"the IMU failed: {self._error}")
        try:
            return self._queue.get_nowait()
        except queue.Empty:
            return None

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._imu.close()


def _live(
    args: argparse.Namespace, settings: ProcedureSettings
) -> tuple[Devices, CameraSettings, Calibration, Console, list[Any]]:
    """The board's devices, its camera settings, the starting calibration, the
    console (recording when asked), and what to close at the end."""
    board = Board.load(args.board)
    nominal = Calibration.load(calibration_in_use(board, args.calibration))
    clock = MonotonicClock()
    bus = open_i2c(board.imu.bus)
    chip = Lsm6dsox(bus, clock, board.imu.address, board.imu.config, f"/dev/i2c-{board.imu.bus}")
    chip.start()
    imu: Imu = PolledImu(chip, board.imu.config.rate_hz, clock)
    display = FramebufferDisplay(board.display_device)
    rig = OakRig(board.depth, board.camera, clock)
    nominal = nominal.with_depth(rig.depth.model)
    writer = None
    if args.record is not None:
        meta = {"source": "device", "board": board.name, "command": "calibrate"}
        writer = SessionWriter(args.record, nominal, meta, clock.now_ns())
        writer.attach_json(
            schemas.CAMERA_ATTACHMENT, camera_attachment(rig.camera.intrinsics, rig.camera.size)
        )
        writer.attach_json(
            schemas.CAPTURE_ATTACHMENT,
            capture_settings(board.camera, settings.max_poses, settings.plan.min_poses),
        )
    console = Console(writer)
    devices = Devices(LiveShow(display, clock, console), rig.camera, rig.depth, imu, clock)
    closing = [rig, display, imu] + ([writer] if writer is not None else [])
    return devices, board.camera, nominal, console, closing


def run(args: argparse.Namespace) -> int:
    closing: list[Any] = []
    if args.replay is not None and args.record is not None:
        raise CalibrationError("--record records the device; it cannot go with --replay")
    if args.replay is not None:
        rc = recorded_capture(args.replay)
        settings = rc.settings
        devices, camera, nominal, console = rc.devices, rc.camera, rc.nominal, Console()
    else:
        if args.max_poses < 1:
            raise CalibrationError("--max-poses must be at least 1")
        settings = ProcedureSettings(
            max_poses=args.max_poses,
            plan=PlanSettings(min_poses=min(PlanSettings().min_poses, args.max_poses)),
        )
        devices, camera, nominal, console, closing = _live(args, settings)
    try:
        outcome = calibrate(devices, camera, nominal, args.out, console, args.force, settings)
    finally:
        for c in closing:
            c.close()
    for path in outcome.written:
        print(f"wrote {path}")
    if outcome.refused:
        raise CalibrationError(outcome.refused)
    return 0
