"""``adaproj run``: the projector's runtime on the board."""

from __future__ import annotations

import argparse
import logging
import os
import signal
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from adaproj_edge.commands._outputs import check_output_dir, check_output_file
from adaproj_edge.resources import DEVICE_CALIBRATION

if TYPE_CHECKING:
    from adaproj_edge.hal.board import Board

log = logging.getLogger(__name__)

EXIT_MISSING = 1
"""``--check``'s exit status when a device file is missing."""


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "run",
        help="run the projector (button, sensors, warp, serial link) on the board",
        description="Boot, show the active content, and wait for the button: press to "
        "capture the surface and project, double press for the next content item, long "
        "press to toggle content-aware / plain projection. Content and settings arrive "
        "over the USB serial link. With --check: load the board and its calibration, "
        "say which device files are there, and stop (opens nothing; exit status 1 when one is "
        "missing: `adaproj doctor` checks each device and says what to do).",
    )
    p.add_argument("--board", default="rpi5-oakd", help="board name or board TOML file")
    p.add_argument(
        "--store", type=Path, default=Path("/var/lib/adaproj/content"), help="content store"
    )
    p.add_argument(
        "--state",
        type=Path,
        default=Path("/var/lib/adaproj/state"),
        help="where the last good warp is kept (shown at the next boot)",
    )
    p.add_argument(
        "--calibration",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help=f"calibration file (default: {DEVICE_CALIBRATION}, written by `adaproj "
        "calibrate`, when it exists; else the board's nominal calibration)",
    )
    p.add_argument(
        "--record",
        type=Path,
        default=None,
        metavar="FILE.mcap",
        help="also record a session of the run: depth, IMU, button and the serial link's "
        "traffic (replay it with `adaproj replay`)",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="start-up checks only: load the board and calibration, list the devices, exit "
        "(1 when one is missing)",
    )
    p.set_defaults(run=run)


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def check(board: Board) -> list[str]:
    """What ``run`` would start from, as lines: the board and its calibration file, the
    projector and depth camera they describe, and each device file, there or not
    (looked at, not opened)."""
    cal = board.calibration()
    p = cal.projector
    d = board.depth
    lines = [
        f"board {board.name}, calibration {board.calibration_path}",
        f"projector {p.width}x{p.height}; depth camera {d.width}x{d.height} at {d.fps:g} fps "
        "(an OAK-D on USB, looked for when the runtime starts)",
    ]
    devices = (
        ("display", board.display_device, ""),
        ("IMU", f"/dev/i2c-{board.imu.bus}", f" (address 0x{board.imu.address:02X})"),
        ("button", board.button_device, ""),
        ("serial link", board.serial_device, ""),
    )
    for what, path, note in devices:
        there = "present" if os.path.exists(path) else "missing"
        lines.append(f"{what}: {path}{note} {there}")
    return lines


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.hal.board import Board, calibration_in_use

    board = Board.load(args.board)
    board = board.with_calibration(calibration_in_use(board, args.calibration))
    if args.check:
        lines = check(board)
        for line in lines:
            print(line)
        missing = sum(line.endswith(" missing") for line in lines)
        if missing:
            print(f"{missing} device(s) missing: `adaproj doctor` says what to do")
            return EXIT_MISSING
        return 0
    log.info("calibration: %s", board.calibration_path)
    board.calibration()  # a bad file is refused before the devices start
    check_output_dir(args.store, "content store")
    check_output_dir(args.state, "state folder")
    if args.record is not None:
        check_output_file(args.record, "recording")

    from adaproj_edge.app.live import run_device

    previous = signal.signal(signal.SIGTERM, _interrupt)  # systemd's stop: close the recording
    try:
        run_device(board, args.store, args.state, record=args.record)
    except KeyboardInterrupt:
        log.info("stopped")
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0
