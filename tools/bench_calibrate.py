#!/usr/bin/env python3
"""The solve time of `adaproj calibrate` on one core (target: under 10 s for 6 poses).

    .venv/bin/python tools/bench_calibrate.py                  # a simulated 6-pose session
    .venv/bin/python tools/bench_calibrate.py SESSION.mcap     # a recorded one

The session (by default a 6-pose calibration session simulated in front of a wall
corner, 640x400 camera) is read into memory first; then, pinned to one core, the
procedure runs on it as `adaproj calibrate --replay` does — decoding each pose's 44
captures, its point pairs and the scene's planes — and the calibration is solved (the
projector model and T_P_D, then R_P_I). Best of --repeat runs, wall and CPU time per
step, next to a fixed numpy workload measured in the same run (the machine is shared:
the ratio says more than the seconds).
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

from adaproj_edge.hal.board import Board  # noqa: E402
from adaproj_edge.procam.procedure import Silent  # noqa: E402
from adaproj_edge.procam.result import solve_capture  # noqa: E402
from adaproj_edge.procam.session_devices import recorded_capture, run_recorded  # noqa: E402
from adaproj_edge.session.calibration_sim import (  # noqa: E402
    CalibrationSimSettings,
    perturbed_rig,
    simulate_calibration,
)
from adaproj_edge.session.simulator import Scene  # noqa: E402


def reference() -> float:
    """Seconds of a fixed numpy workload (the yardstick of this run)."""
    a = np.random.default_rng(0).normal(size=(400, 400))
    t = time.perf_counter()
    for _ in range(20):
        a = np.tanh(a @ a * 1e-3)
    return time.perf_counter() - t


def once(path: Path) -> tuple[float, float, float, float, int]:
    """(capture wall, capture CPU, solve wall, solve CPU, poses) of one replay."""
    rc = recorded_capture(path)  # read into memory: not timed
    w0, c0 = time.perf_counter(), time.process_time()
    run = run_recorded(rc, Silent())
    w1, c1 = time.perf_counter(), time.process_time()
    solve_capture(run, rc.nominal)
    w2, c2 = time.perf_counter(), time.process_time()
    return w1 - w0, c1 - c0, w2 - w1, c2 - c1, len(run.poses)


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("session", nargs="?", default=None, help="calibration session (.mcap)")
    ap.add_argument("--repeat", type=int, default=3, help="runs (best of)")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.session) if args.session else Path(tmp) / "corner-6.mcap"
        if args.session is None:
            nominal = Board.load("rpi5-oakd").calibration()
            print("simulating a 6-pose calibration session ...", flush=True)
            simulate_calibration(
                Scene.load("corner"), perturbed_rig(nominal, seed=3), nominal, path,
                CalibrationSimSettings(poses=6, seed=3),
            )  # fmt: skip
        runs = []
        refs = []
        for _ in range(args.repeat):
            refs.append(reference())
            runs.append(once(path))
    best = np.min(np.array([r[:4] for r in runs]), axis=0)
    ref = min(refs)
    poses = runs[0][4]
    total = best[0] + best[2]
    print(f"{poses} poses, one core, best of {args.repeat}:")
    print(f"  capture replay (decode, pairs, planes) {best[0]:6.2f} s wall {best[1]:6.2f} s CPU")
    print(f"  solve (projector, T_P_D, R_P_I)        {best[2]:6.2f} s wall {best[3]:6.2f} s CPU")
    print(f"  total                                  {total:6.2f} s wall (target < 10 s)")
    print(f"  reference workload {ref:.3f} s: total = {total / ref:.1f}x reference")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
