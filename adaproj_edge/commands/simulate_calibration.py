"""``adaproj simulate-calibration``: a calibration session from a simulated device."""

from __future__ import annotations

import argparse
import logging
from dataclasses import replace
from pathlib import Path
from typing import Any

from adaproj_edge.errors import InputError

log = logging.getLogger(__name__)

FAULTS: dict[str, dict[str, Any]] = {
    "projector-off": {"projector_off": True},
    "shake": {"shake_pose": 1},
    "saturated": {"exposure_scale": 6.0},
}
"""Bad input to simulate: ``SimFaults`` fields by name (kept light: this module is
imported for ``--help``)."""


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "simulate-calibration",
        help="simulate `adaproj calibrate` on a virtual rig; write the calibration session",
        description="Runs the calibration procedure on a simulated device whose true rig "
        "(--rig, a calibration TOML that differs from the board's nominal one) stands in "
        "front of a built-in surface or a mesh: the camera sees the projected patterns "
        "(shadows, camera noise and blur, ambient light, projector gamma and black level), "
        "depth comes through the OAK-D stereo error model, the IMU feels the moves between "
        "poses. The session records the nominal calibration and holds the true rig as "
        "ground truth; `adaproj calibrate --replay` solves from it.",
    )
    p.add_argument(
        "--surface", required=True, help="built-in surface (corner, plane, wall-floor, ...) or MESH"
    )
    p.add_argument(
        "--rig",
        required=True,
        help="the true rig: a calibration TOML/JSON (e.g. a copy of "
        "hw/calibration/rpi5-oakd.toml with a value changed)",
    )
    p.add_argument("--poses", type=int, default=5, help="poses to capture")
    p.add_argument("--out", required=True, help="session file to write (.mcap)")
    p.add_argument("--board", default="rpi5-oakd", help="board: nominal calibration and camera")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same file)")
    p.add_argument(
        "--camera", default="640x400", metavar="WxH", help="camera frame size (default 640x400)"
    )
    p.add_argument("--fault", choices=sorted(FAULTS), default=None, help="simulate bad input")
    p.set_defaults(run=run)


def parse_size(text: str) -> tuple[int, int]:
    """``"640x400"`` -> (640, 400)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"camera size {text!r} is not WIDTHxHEIGHT") from None
    return w, h


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.hal.board import Board
    from adaproj_edge.session.calibration_sim import (
        CalibrationSimSettings,
        SimFaults,
        simulate_calibration,
    )
    from adaproj_edge.session.simulator import Scene

    board = Board.load(args.board)
    nominal = board.calibration()
    truth = Calibration.load(args.rig)
    w, h = parse_size(args.camera)
    settings = CalibrationSimSettings(
        poses=args.poses,
        seed=args.seed,
        camera=replace(board.camera, width=w, height=h),
        faults=SimFaults(**FAULTS[args.fault]) if args.fault else SimFaults(),
    )

    def tell(event: str, message: str) -> None:
        print(message, flush=True)

    n = simulate_calibration(
        Scene.load(args.surface), truth, nominal, Path(args.out), settings, tell
    )
    print(f"wrote {n} records to {args.out}")
    return 0
