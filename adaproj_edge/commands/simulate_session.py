"""``adaproj simulate-session``: a recorded session from a virtual device."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from adaproj_edge.commands._outputs import check_output_file

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "simulate-session",
        help="simulate a hand-held device in front of a surface; write a session file",
        description="A virtual device held in a hand (smooth path, still phases, tremor) "
        "in front of a built-in surface or a triangle mesh (.obj/.ply, metres, in the "
        "projector frame at the start): OAK-D-like depth frames, LSM6DSOX-like IMU "
        "samples, button presses, and the ground truth on channels of its own.",
    )
    p.add_argument("--surface", required=True, help="built-in surface name, or MESH.obj|.ply")
    p.add_argument("--seconds", type=float, default=5.0, help="length of the session")
    p.add_argument("--out", required=True, help="session file to write (.mcap)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same file)")
    p.add_argument("--depth-fps", type=float, default=15.0, help="depth frames per second")
    p.add_argument("--calibration", default=None, help="calibration TOML/JSON (default: nominal)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_output_file(args.out, "session file")

    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session

    cal = Calibration.load(args.calibration) if args.calibration else Calibration.default()
    settings = SimulationSettings(seconds=args.seconds, depth_fps=args.depth_fps, seed=args.seed)
    n = simulate_session(Scene.load(args.surface), args.out, cal, settings)
    log.info("wrote %d records to %s", n, args.out)
    return 0
