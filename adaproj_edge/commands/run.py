"""``adaproj run``: the projector's runtime on the board."""

from __future__ import annotations

import argparse
import logging
import signal
from pathlib import Path
from types import FrameType
from typing import Any

from adaproj_edge.app.live import run_device
from adaproj_edge.hal.board import DEVICE_CALIBRATION, Board, calibration_in_use

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "run",
        help="run the projector (button, sensors, warp, serial link) on the board",
        description="Boot, show the active content, and wait for the button: press to "
        "capture the surface and project, double press for the next content item, long "
        "press to toggle content-aware / plain projection. Content and settings arrive "
        "over the USB serial link.",
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
    p.set_defaults(run=run)


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    board = Board.load(args.board)
    board = board.with_calibration(calibration_in_use(board, args.calibration))
    log.info("calibration: %s", board.calibration_path)
    board.calibration()  # a bad file is refused before the devices start
    previous = signal.signal(signal.SIGTERM, _interrupt)  # systemd's stop: close the recording
    try:
        run_device(board, args.store, args.state, record=args.record)
    except KeyboardInterrupt:
        log.info("stopped")
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0
