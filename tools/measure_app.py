#!/usr/bin/env python3
"""Displayed distortion of the device runtime against the warp from the true surface,
on longer simulated sessions than the committed fixtures.

    .venv/bin/python tools/measure_app.py                       # 4 scenes, 20 s each
    .venv/bin/python tools/measure_app.py --scenes corner --seconds 40

Each session: the hand moves and settles again and again (1 s still, 0.8 s moving), 15
depth frames a second, one press at the start. Every content-aware frame the runtime
shows is scored on the session's ground truth (tests' scorer in app/replay.py): angle
distortion of the displayed map next to the engine's full-grid warp computed from the
true surface at that moment. Prints, per scene, the ratio shown / truth (mean,
median, max, share within 2x) and how many content-aware updates found their
content-free warp in the pose cache.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.session.simulator import (  # noqa: E402
    Scene,
    SimulationSettings,
    simulate_session,
)
from adaproj_edge.threads import apply_thread_policy  # noqa: E402

SCENES = ("corner", "cylinder-convex", "sphere-convex", "bowl")


def main() -> int:
    apply_thread_policy()
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), help="simulated surfaces")
    ap.add_argument("--seconds", type=float, default=20.0, help="length of each session")
    ap.add_argument("--seed", type=int, default=21, help="simulation seed")
    args = ap.parse_args()
    print(
        f"{'scene':16s} {'frames':>6s} {'mean':>6s} {'median':>6s} {'max':>6s} {'<=2x':>6s}  cache"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes:
            path = Path(tmp) / f"{scene}.mcap"
            settings = SimulationSettings(
                seconds=args.seconds, depth_fps=15.0, seed=args.seed, presses=(0.2,)
            )
            simulate_session(Scene.load(scene), path, settings=settings)
            r = replay_session(path, None, ReplayOptions())
            ratio = np.array(
                [d["shown_angle_error"] / d["truth_angle_error"] for d in r["distortion"]]
            )
            aware = [u for u in r["updates"] if u["kind"] == "content-aware"]
            hits = sum(bool(u["cache_hit"]) for u in aware)
            if ratio.size == 0:
                print(f"{scene:16s} no content-aware frame scored")
                continue
            print(
                f"{scene:16s} {ratio.size:6d} {ratio.mean():6.2f} {np.median(ratio):6.2f} "
                f"{ratio.max():6.2f} {np.mean(ratio <= 2.0):6.0%}  {hits}/{len(aware)} hits",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
