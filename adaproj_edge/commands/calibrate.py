"""``adaproj calibrate``: the projector, depth camera and IMU from structured light."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from adaproj_edge.errors import CalibrationError
from adaproj_edge.resources import DEVICE_CALIBRATION

if TYPE_CHECKING:  # the rest is imported when the command runs (--help stays light)
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.hal.camera import CameraSettings
    from adaproj_edge.procam.procedure import Devices, ProcedureSettings
    from adaproj_edge.session.codec import Record
    from adaproj_edge.session.writer import SessionWriter

log = logging.getLogger(__name__)

MAX_POSES = 8
"""Poses captured at most by default (``ProcedureSettings.max_poses``)."""


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
    p.add_argument(
        "--max-poses",
        type=int,
        default=None,
        help=f"stop after this many poses (default {MAX_POSES}; live capture only: a replay "
        "solves the poses its session recorded)",
    )
    p.add_argument(
        "--photometric",
        action="store_true",
        help="also measure the surface's colour and the room's light at the first pose "
        "(three more captures: the projector's primaries); written as "
        "OUT.photometric.npz (live capture only: a replay measures when its session did)",
    )
    p.set_defaults(run=run)


class Console:
    """Tells the user what the procedure says (stdout); records into a session."""

    def __init__(self, writer: SessionWriter | None = None) -> None:
        self.writer = writer

    def say(self, event: str, message: str) -> None:
        """Print ``message``; the session is flushed after each capture and at the end."""
        print(message, flush=True)
        if self.writer is not None and event in ("captured", "done"):
            self.writer.flush()

    def record(self, rec: Record) -> None:
        """Write ``rec`` into the session, when recording."""
        if self.writer is not None:
            self.writer.write(rec)


def _live(
    args: argparse.Namespace, settings: ProcedureSettings
) -> tuple[Devices, CameraSettings, Calibration, Console, list[Any]]:
    """The board's devices, its camera settings, the starting calibration, the
    console (recording when asked), and what to close at the end."""
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.hal.board import Board, calibration_in_use
    from adaproj_edge.hal.camera import OakRig
    from adaproj_edge.hal.clock import MonotonicClock
    from adaproj_edge.hal.display import FramebufferDisplay
    from adaproj_edge.hal.imu import Imu
    from adaproj_edge.hal.lsm6dsox import Lsm6dsox, open_i2c
    from adaproj_edge.hal.polled_imu import PolledImu
    from adaproj_edge.procam.procedure import Devices, LiveShow
    from adaproj_edge.session import schemas
    from adaproj_edge.session.calibration_sim import camera_attachment, capture_settings
    from adaproj_edge.session.writer import SessionWriter

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
    from adaproj_edge.procam.outputs import calibrate
    from adaproj_edge.procam.plan import PlanSettings
    from adaproj_edge.procam.procedure import ProcedureSettings
    from adaproj_edge.procam.session_devices import recorded_capture

    closing: list[Any] = []
    if args.max_poses is not None and args.max_poses < 1:
        raise CalibrationError(f"--max-poses must be at least 1, got {args.max_poses}")
    if args.replay is not None and args.record is not None:
        raise CalibrationError("--record records the device; it cannot go with --replay")
    if args.replay is not None and args.max_poses is not None:
        raise CalibrationError(
            "--max-poses limits the live capture; a replay solves the poses its session recorded"
        )
    if args.replay is not None:
        rc = recorded_capture(args.replay)
        settings = rc.settings
        devices, camera, nominal, console = rc.devices, rc.camera, rc.nominal, Console()
    else:
        max_poses = MAX_POSES if args.max_poses is None else args.max_poses
        settings = ProcedureSettings(
            max_poses=max_poses,
            plan=PlanSettings(min_poses=min(PlanSettings().min_poses, max_poses)),
            photometric=args.photometric,
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
