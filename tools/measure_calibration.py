#!/usr/bin/env python3
"""How well `adaproj calibrate` recovers a rig, and what that is worth on the wall.

    .venv/bin/python tools/measure_calibration.py               # both tables
    .venv/bin/python tools/measure_calibration.py --accuracy    # recovery only
    .venv/bin/python tools/measure_calibration.py --payoff      # (a)/(b)/(c) only

Accuracy: calibration sessions are simulated (`adaproj simulate-calibration`: the
procedure run on a simulated device, 640x400 camera) for true rigs off the board's
nominal calibration by focal +-3 %, principal point (+-15, +300) px, T_P_D 2 deg and
15 mm, R_P_I 5 deg, in front of a wall corner (4, 5 and 6 poses, both signs), a wall
and the floor, and one flat wall; each is solved from its recording (`adaproj
calibrate --replay`) and compared with the true rig.

Payoff: a hand-held session (the runtime's own simulator, --seconds long, in front of
the corner) is simulated on a perturbed rig, recording the NOMINAL calibration while
the world follows the true one, and replayed with (a) the nominal calibration, (b)
the calibration solved from a calibration session of that rig, (c) the true rig. Each
content-aware frame the runtime shows is scored on the true surface as the true
projector lights it (the replay's ground-truth scorer); the table gives the mean and
median angle distortion of the displayed frames, and their ratio to (c).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.geometry.calibration import Calibration  # noqa: E402
from adaproj_edge.hal.board import Board  # noqa: E402
from adaproj_edge.procam.procedure import Silent  # noqa: E402
from adaproj_edge.procam.report import changes, judge  # noqa: E402
from adaproj_edge.procam.result import CalibrationResult, solve_capture  # noqa: E402
from adaproj_edge.procam.session_devices import recorded_capture, run_recorded  # noqa: E402
from adaproj_edge.session.calibration_sim import (  # noqa: E402
    CalibrationSimSettings,
    perturbed_rig,
    simulate_calibration,
)
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session  # noqa: E402

# (scene, poses, sign of the focal and horizontal principal point change, seed)
CASES = [
    ("corner", 4, +1, 1),
    ("corner", 5, -1, 2),
    ("corner", 6, +1, 3),
    ("wall-floor", 5, +1, 4),
    ("plane", 5, -1, 5),
]


def nominal() -> Calibration:
    return Board.load("rpi5-oakd").calibration()


def solve_session(path: Path) -> CalibrationResult:
    """`adaproj calibrate --replay`, without writing files."""
    rc = recorded_capture(path)
    run = run_recorded(rc, Silent())
    return solve_capture(run, rc.nominal)


def rig(sign: float, seed: int) -> Calibration:
    return perturbed_rig(nominal(), focal=0.03 * sign, principal_px=(15 * sign, 300), seed=seed)


def accuracy(tmp: Path) -> None:
    print(
        f"{'scene':11s} {'poses':>5s} {'focal %':>8s} {'pp px':>6s} {'T deg':>6s} {'T mm':>6s} "
        f"{'R_P_I deg':>9s} {'RMS px':>6s}  verdict"
    )
    for scene, poses, sign, seed in CASES:
        truth = rig(sign, seed)
        path = tmp / f"{scene}-{poses}-{seed}.mcap"
        settings = CalibrationSimSettings(poses=poses, seed=seed)
        simulate_calibration(Scene.load(scene), truth, nominal(), path, settings)
        t0 = time.process_time()
        result = solve_session(path)
        cpu = time.process_time() - t0
        err = changes(result.calibration, truth)
        verdict = judge(result)
        print(
            f"{scene:11s} {poses:5d} {err['focal_pct']:8.4f} {err['principal_px']:6.3f} "
            f"{err['T_P_D_deg']:6.4f} {err['T_P_D_mm']:6.3f} {err['R_P_I_deg']:9.3f} "
            f"{result.projector.rms_px:6.3f}  {verdict.level} (R_P_I +-{result.imu.sigma_deg:.2f} "
            f"deg; {cpu:.1f} s CPU)",
            flush=True,
        )
        if verdict.level == "refused":
            print(f"{'':11s} {verdict.line}")


def payoff(tmp: Path, seconds: float) -> None:
    truth = rig(+1, 7)
    cal_path = tmp / "payoff-calibration.mcap"
    simulate_calibration(
        Scene.load("corner"), truth, nominal(), cal_path, CalibrationSimSettings(poses=5, seed=7)
    )
    solved = solve_session(cal_path)
    print(f"calibration session: {judge(solved).line}")
    hand = tmp / "payoff-handheld.mcap"
    settings = SimulationSettings(seconds=seconds, depth_fps=15.0, seed=21, presses=(0.2,))
    simulate_session(Scene.load("corner"), hand, nominal(), settings, truth=truth)
    rows = [("(a) nominal", None), ("(b) solved", solved.calibration), ("(c) true rig", truth)]
    means = {}
    print(f"{'replayed with':14s} {'frames':>6s} {'mean':>7s} {'median':>7s} {'vs (c)':>7s}")
    results = []
    for name, cal in rows:
        r = replay_session(hand, None, ReplayOptions(calibration=cal))
        shown = np.array([d["shown_angle_error"] for d in r["distortion"]])
        means[name] = float(shown.mean()) if shown.size else float("nan")
        results.append((name, shown))
    ref = means["(c) true rig"]
    for name, shown in results:
        print(
            f"{name:14s} {shown.size:6d} {shown.mean():7.4f} {np.median(shown):7.4f} "
            f"{shown.mean() / ref:6.2f}x",
            flush=True,
        )


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--accuracy", action="store_true", help="only the recovery table")
    ap.add_argument("--payoff", action="store_true", help="only the (a)/(b)/(c) table")
    ap.add_argument("--seconds", type=float, default=12.0, help="hand-held session length")
    args = ap.parse_args()
    both = not (args.accuracy or args.payoff)
    with tempfile.TemporaryDirectory() as d:
        if args.accuracy or both:
            accuracy(Path(d))
        if args.payoff or both:
            payoff(Path(d), args.seconds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
