#!/usr/bin/env python3
"""Benchmark the device runtime on a replayed session, on one core.

    .venv/bin/python tools/bench_app.py                   # a simulated 12-s session
    .venv/bin/python tools/bench_app.py --scene corner    # ... in front of a wall corner
    .venv/bin/python tools/bench_app.py SESSION.mcap
    .venv/bin/python tools/bench_app.py --real --cpu     # recorded real depth, CPU time

Replays the session in the same run with the per-pose warp cache and warm starts
(the product) and with both turned off, interleaved ``--repeat`` times; per stage the
run least disturbed by other load is reported. Prints the time per stage (median,
p95) side by side, the motion-to-frame latency (session time from the IMU seeing the
motion to the depth frame that triggered the new warp, plus the compute time of that
update), and what a cache hit costs (lookup + check against the current depth).

``update_<kind>`` is an update from the surface to the frame on the display: the
content-free warp from the pose cache or solved, the content-aware refinement (for
``content-aware``), the display maps, the render and the display.
``depth_to_frame_<kind>`` adds what comes before it: the depth frame's surface
estimate (``surface``), the temporal average and the wall snapping (``planes``).
``refine_prep``: what a settled device measures of a content-free warp alone in the
frame it makes it (nothing shown), so that its first refinement does not.
Targets on one core: content-aware update <= 33 ms p95 at the default grid, cache hit
<= 1 ms.

``--cpu``: the stages' CPU time (``time.process_time``, one thread) instead of wall
time: on a machine other work shares, wall times measure the others. ``--real``: instead
of a session, the device (the runtime on a virtual clock, as ``tools/bench_real.py`` runs
it) held still before each region of the recorded real frames of
``tests/fixtures/real/``, ``--depth-frames`` copies of the frame each; the stages'
samples of all regions pooled.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.app.settings import AppSettings  # noqa: E402
from adaproj_edge.app.telemetry import StageTimes  # noqa: E402
from adaproj_edge.arrays import FloatArray  # noqa: E402
from adaproj_edge.geometry.calibration import Calibration  # noqa: E402
from adaproj_edge.session.records import TruthPose  # noqa: E402
from adaproj_edge.session.simulator import (  # noqa: E402
    Scene,
    SimulationSettings,
    simulate_session,
    true_surface,
)
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from adaproj_edge.warp.engine import WarpSettings  # noqa: E402
from adaproj_edge.warp.planner import WarpPlanner  # noqa: E402
from adaproj_edge.warp.posecache import PoseCache  # noqa: E402

STAGES = [
    "surface",
    "planes",
    "cache_lookup",
    "content_free",
    "re_place",
    "refine_prep",
    "content_aware",
    "map",
    "render",
    "show",
    "cache_hit",
    "update_content-free",
    "update_content-aware",
    "depth_to_frame_content-free",
    "depth_to_frame_content-aware",
]


def _fmt(t: dict[str, Any] | None) -> str:
    if t is None:
        return f"{'-':>22s}"
    return f"{t['median_ms']:8.2f} / {t['p95_ms']:8.2f} ({t['n']:3d})"


def _best(runs: list[dict[str, Any]], stage: str) -> dict[str, Any] | None:
    """The stage's figures from the run where its median was lowest (least disturbed by
    other load on the core)."""
    got = [r["timings_ms"][stage] for r in runs if stage in r["timings_ms"]]
    return min(got, key=lambda t: t["median_ms"]) if got else None


@dataclass
class _Entry:
    depth: FloatArray
    frames: int = 1


def cache_hit_cost(repeats: int = 2000) -> tuple[float, float]:
    """Median and p95 (ms) of a pose-cache hit (lookup + depth check) on the default
    21x21 lattice with 8 entries."""
    cal = Calibration.default()
    scene = Scene.load("cylinder-convex")
    origin = TruthPose(0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    surface = true_surface(scene, origin, cal.projector, (21, 21))
    cf = WarpPlanner(cal.projector).content_free(surface, (960, 600), WarpSettings())
    entry = _Entry(cf.depth)
    cache: PoseCache[_Entry] = PoseCache(8)
    for k in range(8):
        cache.put((k,), _Entry(entry.depth * (1 + 0.02 * k)))
    times = []
    for i in range(repeats):
        k = i % 8
        depth = entry.depth * (1 + 0.02 * k)
        t0 = time.perf_counter()
        hit = cache.get((k,), depth)
        times.append(time.perf_counter() - t0)
        assert hit is not None
    a = np.asarray(times) * 1e3
    return float(np.median(a)), float(np.percentile(a, 95))


def real_runs(flag: bool, depth_frames: int, cpu: bool) -> tuple[dict[str, Any], list[str]]:
    """The device before every region of the real frames (caching and warm starts
    ``flag``): the stages' samples of all regions pooled, in the shape of a replay's
    summary (``timings_ms``, ``updates``, ``counters``), and what each region showed."""
    from tests.realframes import load_frames, run_runtime

    s = replace(AppSettings(), caching=flag, warm_start=flag)
    pooled = StageTimes()
    updates: list[dict[str, Any]] = []
    counters: dict[str, int] = {}
    shown = []
    for frame in load_frames():
        for region in frame.regions:
            run = run_runtime(
                frame,
                region,
                settings=s,
                depth_frames=depth_frames,
                stage_clock=time.process_time if cpu else None,
            )
            shown.append(f"{frame.name}/{region.name}: {run.kind or run.error}")
            assert run.telemetry is not None
            for stage, xs in run.telemetry.times.samples.items():
                for x in xs:
                    pooled.add(stage, x)
            updates += run.telemetry.updates
            for k, v in run.telemetry.counters.items():
                counters[k] = counters.get(k, 0) + v
    summary = {
        "session": "real frames",
        "timings_ms": pooled.summary(),
        "updates": updates,
        "counters": counters,
        "motion_to_frame_ms": {"median": "-", "p95": "-", "n": 0},
        "rss_mb": [0.0],
    }
    return summary, shown


def main() -> int:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("session", nargs="?", help="session file (default: simulate one)")
    ap.add_argument("--seconds", type=float, default=12.0, help="length of the simulated session")
    ap.add_argument("--scene", default="cylinder-convex", help="surface of the simulated session")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each (best one reported)")
    ap.add_argument("--cpu", action="store_true", help="CPU time per stage, not wall time")
    ap.add_argument("--real", action="store_true", help="the recorded real frames, no session")
    ap.add_argument("--depth-frames", type=int, default=12, help="--real: depth frames per region")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    runs: dict[str, list[dict[str, Any]]] = {"cache+warm": [], "off": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.session) if args.session else Path(tmp) / "bench.mcap"
        if args.real:
            shown: list[str] = []
            for k in range(args.repeat):
                order = (("cache+warm", True), ("off", False))
                for label, flag in order if k % 2 == 0 else order[::-1]:
                    t0 = time.perf_counter()
                    r, shown = real_runs(flag, args.depth_frames, args.cpu)
                    r["wall_s"] = time.perf_counter() - t0
                    runs[label].append(r)
            print("shown: " + "; ".join(shown))
        elif not args.session:
            settings = SimulationSettings(
                seconds=args.seconds, depth_fps=15.0, seed=5, presses=(0.2,)
            )
            simulate_session(Scene.load(args.scene), path, settings=settings)
        if not args.real:
            # a replay to warm up (imports, allocator, caches of the OS), not reported
            replay_session(path, None, ReplayOptions(score=False))
        for k in range(0 if args.real else args.repeat):  # interleaved: a busy spell hits both
            order = (("cache+warm", True), ("off", False))
            for label, flag in order if k % 2 == 0 else order[::-1]:
                s = replace(AppSettings(), caching=flag, warm_start=flag)
                opts = ReplayOptions(s, score=False, cpu_times=args.cpu)
                t0 = time.perf_counter()
                r = replay_session(path, None, opts)
                r["wall_s"] = time.perf_counter() - t0
                runs[label].append(r)
    on, off = runs["cache+warm"], runs["off"]
    length = "" if args.real else f": {on[0]['duration_s']:.1f} s"
    print(
        f"session {on[0]['session']}{length}; one core; {'CPU' if args.cpu else 'wall'} ms "
        f"median / p95 (count), best of {args.repeat} interleaved runs"
    )
    print(f"{'stage':22s} {'cache+warm':>24s}   {'off':>24s}")
    for st in STAGES:
        print(f"{st:22s} {_fmt(_best(on, st))}   {_fmt(_best(off, st))}")
    for label, rs in runs.items():
        r = min(rs, key=lambda x: x["wall_s"])
        lat = r["motion_to_frame_ms"]
        c = r["counters"]
        its = [u["iterations"] for u in r["updates"] if u["kind"] == "content-aware"]
        print(
            f"{label:10s}: motion-to-frame latency median {lat['median']} ms, p95 {lat['p95']} ms "
            f"(n={lat['n']}); {c['content_free']} content-free solves "
            f"(+{c.get('re_placed', 0)} re-placed for another up), "
            f"{c['content_aware']} content-aware "
            f"(mean {np.mean(its) if its else 0:.1f} iterations), {c['cache_hits']} cache hits; "
            f"replay {r['wall_s']:.1f} s wall; RSS max {max(r['rss_mb']):.0f} MB"
        )
    for label, rs in runs.items():
        r = min(rs, key=lambda x: x["timings_ms"]["update_content-aware"]["median_ms"])
        parts = []
        for hit in (True, False):
            ms = [
                u["update_ms"]
                for u in r["updates"]
                if u["kind"] == "content-aware" and u["cache_hit"] is hit
            ]
            if ms:
                parts.append(
                    f"{'hit' if hit else 'miss'} {np.median(ms):.1f} / {np.max(ms):.1f} ms "
                    f"(median / max of {len(ms)})"
                )
        print(f"{label:10s}: content-aware updates by pose cache: " + "; ".join(parts))
    med, p95 = cache_hit_cost()
    print(f"pose-cache hit (lookup + depth check): median {med:.3f} ms, p95 {p95:.3f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
