"""``adaproj simulate-session``: a recorded session from a virtual device."""

from __future__ import annotations

import argparse
import logging
from dataclasses import replace
from typing import Any

from adaproj_edge.commands._outputs import check_output_file
from adaproj_edge.errors import InputError

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "simulate-session",
        help="simulate a hand-held device in front of a surface; write a session file",
        description="A virtual device held in a hand (smooth path, still phases, tremor, "
        "slow sway, optionally rolled) "
        "in front of a built-in surface or a triangle mesh (.obj/.ply, metres, in the "
        "projector frame at the start): OAK-D-like depth frames, LSM6DSOX-like IMU "
        "samples, button presses, and the ground truth on channels of its own.",
    )
    p.add_argument(
        "--surface",
        required=True,
        help="built-in surface name (a cluttered room: wall-boxes, wall-chair, wall-shelf, "
        "desk-partition), or MESH.obj|.ply",
    )
    p.add_argument("--seconds", type=float, default=5.0, help="length of the session")
    p.add_argument("--out", required=True, help="session file to write (.mcap)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same file)")
    p.add_argument("--depth-fps", type=float, default=15.0, help="depth frames per second")
    p.add_argument("--calibration", default=None, help="calibration TOML/JSON (default: nominal)")
    p.add_argument(
        "--tremor",
        type=float,
        default=None,
        metavar="DEG_RMS",
        help="hand tremor (8-12 Hz), degrees RMS about each axis (default 0.005: a steady "
        "hand; 0.1-0.2 is typical of a hand-held projector)",
    )
    p.add_argument(
        "--roll",
        type=float,
        default=0.0,
        metavar="DEG",
        help="the device held rolled by DEG about its optical axis (default 0: level)",
    )
    p.add_argument(
        "--sensor",
        default="oak-d",
        choices=["oak-d", "kinect", "smooth"],  # session.stereo.NOISE_MODELS (no numpy here)
        help="the depth sensor's noise model (default oak-d: depth steps of z^2 / (f B 8), "
        "flying pixels, holes on untextured patches, occlusion bands beside silhouettes; "
        "smooth: smooth noise only, no visible steps)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.tremor is not None and not 0.0 <= args.tremor <= 2.0:
        raise InputError(f"--tremor must be in [0, 2] degrees RMS, got {args.tremor}")
    if not -90.0 <= args.roll <= 90.0:
        raise InputError(f"--roll must be in [-90, 90] degrees, got {args.roll}")
    check_output_file(args.out, "session file")

    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.session.hand import HandMotion
    from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session
    from adaproj_edge.session.stereo import StereoNoise

    cal = Calibration.load(args.calibration) if args.calibration else Calibration.default()
    hand = HandMotion(args.seconds, args.seed, roll_deg=args.roll)
    if args.tremor is not None:
        hand = replace(hand, tremor_deg=args.tremor)
    settings = SimulationSettings(
        seconds=args.seconds,
        depth_fps=args.depth_fps,
        seed=args.seed,
        motion=hand,
        stereo=StereoNoise.named(args.sensor),
    )
    n = simulate_session(Scene.load(args.surface), args.out, cal, settings)
    log.info("wrote %d records to %s", n, args.out)
    return 0
