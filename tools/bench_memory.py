#!/usr/bin/env python3
"""Resident memory of a long replay: does the runtime stay under 300 MB, and flat?

    .venv/bin/python tools/bench_memory.py                 # a simulated 60-s session
    .venv/bin/python tools/bench_memory.py --seconds 120
    .venv/bin/python tools/bench_memory.py SESSION.mcap

Simulates a session in which the hand moves and settles again and again (the
simulator's hand motion, 15 depth frames a second, one button press), replays it
through the device runtime and prints the resident set size sampled during the
replay (every 200 records): at the start of projecting, the plateau (median of the
second half), the peak, and the slope over the second half (MB per minute of
session; growth shows as a steady positive slope).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
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

LIMIT_MB = 300.0


def main() -> int:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("session", nargs="?", help="session file (default: simulate one)")
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the simulated session")
    ap.add_argument("--scene", default="cylinder-convex", help="surface of the simulated session")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.session) if args.session else Path(tmp) / "memory.mcap"
        if not args.session:
            print(f"simulating {args.seconds:g} s of {args.scene} ...", flush=True)
            settings = SimulationSettings(
                seconds=args.seconds, depth_fps=15.0, seed=9, presses=(0.2,)
            )
            simulate_session(Scene.load(args.scene), path, settings=settings)
        t0 = time.perf_counter()
        r = replay_session(path, None, ReplayOptions(score=False))
        wall = time.perf_counter() - t0
    rss = np.asarray(r["rss_mb"], dtype=np.float64)
    duration = float(r["duration_s"])
    half = rss[rss.size // 2 :]
    t = np.linspace(0.0, duration, rss.size)[rss.size // 2 :]
    slope = float(np.polyfit(t / 60.0, half, 1)[0]) if half.size >= 2 else 0.0
    c = r["counters"]
    print(
        f"session {r['session']}: {duration:.1f} s, {c['content_free']} content-free and "
        f"{c['content_aware']} content-aware warps, {c['cache_hits']} cache hits, "
        f"{c['frames_shown']} frames; replay {wall:.1f} s wall"
    )
    print(
        f"RSS MB: first {rss[0]:.0f}, plateau {np.median(half):.0f}, peak {rss.max():.0f} "
        f"(limit {LIMIT_MB:.0f}); second-half slope {slope:+.1f} MB/min "
        f"over {rss.size} samples"
    )
    ok = rss.max() < LIMIT_MB
    print("within the limit" if ok else "OVER THE LIMIT")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
