#!/usr/bin/env python3
"""Time of the guard per call (never worse than conformal, :mod:`adaproj_edge.warp.guard`):
the device's ``guard_grid`` (coarse-to-fine, once per content-aware update) and the
full grid's ``guard`` (``compute_warp``), on analytic surfaces, one core:

    .venv/bin/python tools/bench_guard.py [--tree PATH] [--repeat 7]

``--tree`` imports ``adaproj_edge`` from another checkout (a baseline in the same run
conditions). Prints the median milliseconds per call and the guard's choice.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--tree", default=str(HERE), help="checkout whose adaproj_edge is timed")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--surfaces", default="sphere-convex,bumps")
    ap.add_argument("--masks", default="one-left,quarter")
    args = ap.parse_args()
    sys.path.insert(0, args.tree)
    import adaproj_edge.warp.engine as engine
    import adaproj_edge.warp.planner as planner
    from adaproj_edge.content.contentmap import ContentMap
    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.threads import apply_thread_policy
    from adaproj_edge.warp.engine import WarpSettings

    sys.path.insert(1, str(HERE))
    from tests.warp.conftest import CONTENT, subject_masks

    apply_thread_policy()
    times: dict[str, list[float]] = {"device": [], "full": []}

    def timed(key: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*a: Any, **k: Any) -> Any:
            t0 = time.perf_counter()
            out = fn(*a, **k)
            times[key].append(1000 * (time.perf_counter() - t0))
            return out

        return wrapper

    planner.guard_grid = timed("device", planner.guard_grid)  # type: ignore[assignment]
    engine.guard = timed("full", engine.guard)  # type: ignore[assignment]
    print(f"adaproj_edge from {args.tree}")
    for name in args.surfaces.split(","):
        s = simulate_surface(name)
        for mask in args.masks.split(","):
            cmap = ContentMap(subject_masks()[mask], CONTENT)
            device = planner.WarpPlanner(
                s.projector, plan=planner.PlanSettings(refine_factor=2, warm_start=False)
            )
            start = device.content_free(s, CONTENT, WarpSettings())
            for _ in range(args.repeat):
                device.refine(s, cmap, WarpSettings(), start)
            full = planner.WarpPlanner(s.projector)
            for _ in range(args.repeat):
                warp = full.plan(s, CONTENT, cmap, WarpSettings())
            dev, ful = statistics.median(times["device"]), statistics.median(times["full"])
            print(
                f"{name:14s} {mask:9s} device guard_grid {dev:7.2f} ms"
                f"   full-grid guard {ful:7.2f} ms [{warp.meta['guard']['choice']}]",
                flush=True,
            )
            times["device"].clear()
            times["full"].clear()


if __name__ == "__main__":
    main()
