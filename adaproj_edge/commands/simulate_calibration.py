"""``adaproj simulate-calibration``: a calibration session from a simulated device."""

from __future__ import annotations

import argparse
import logging
from dataclasses import replace
from pathlib import Path
from typing import Any

from adaproj_edge.commands.simulate import ambient_arg
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
    p.add_argument(
        "--photometric",
        action="store_true",
        help="the procedure also captures the projector's primaries at the first pose, as "
        "`adaproj calibrate --photometric` does (its replay measures the surface's colour)",
    )
    p.add_argument(
        "--albedo",
        type=Path,
        help="PNG of the surface's colour (reflectance) as the true projector sees it from "
        "the first pose, resized to its frame and painted onto the surface (default: a "
        "grey procedural texture)",
    )
    p.add_argument(
        "--ambient",
        type=ambient_arg,
        default=None,
        help="the room's light, a fraction of the projector's white on a frontal surface "
        "1.5 m away (default: the simulator's, about 0.13)",
    )
    p.set_defaults(run=run)


def parse_size(text: str) -> tuple[int, int]:
    """``"640x400"`` -> (640, 400)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"camera size {text!r} is not WIDTHxHEIGHT") from None
    return w, h


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.fileio import read_image
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.hal.board import Board
    from adaproj_edge.render.surface_light import albedo_from_image
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
    albedo = None
    if args.albedo is not None:
        p = truth.projector
        albedo = albedo_from_image(read_image(args.albedo), (p.width, p.height))
    optics = CalibrationSimSettings().optics
    if args.ambient is not None:
        optics = replace(optics, ambient=args.ambient * optics.white_level)
    settings = CalibrationSimSettings(
        poses=args.poses,
        seed=args.seed,
        camera=replace(board.camera, width=w, height=h),
        faults=SimFaults(**FAULTS[args.fault]) if args.fault else SimFaults(),
        optics=optics,
        photometric=args.photometric,
        albedo=albedo,
    )

    def tell(event: str, message: str) -> None:
        print(message, flush=True)

    n = simulate_calibration(
        Scene.load(args.surface), truth, nominal, Path(args.out), settings, tell
    )
    print(f"wrote {n} records to {args.out}")
    return 0
