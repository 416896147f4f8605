#!/usr/bin/env python3
"""What the placements cost in a warp: time in ``place`` per warp, one core.

For each surface and grid, ``content`` mode with bench_warp's off-centre subject: the
median over ``--repeat`` warps (``compute_warp`` from scratch) of the time spent in
:func:`adaproj_edge.warp.placement.place` - the cold call (no previous placement: the
upright angle and the rectangle search from the raster) and the warm ones (the
alternation's and the guard's, from the previous placement) - with the number of calls,
and their share of the warp.

    .venv/bin/python tools/bench_placement.py [--grids 20,40] [--repeat 20]

Another tree's placements (e.g. before a change), with the same script:
``PYTHONPATH=/path/to/that/tree .venv/bin/python tools/bench_placement.py``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

from bench_warp import CONTENT, subject_mask

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp import placement
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid


class Timer:
    """Seconds spent in ``place`` (cold, warm) and its calls, since the last reset."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.cold = self.warm = 0.0
        self.calls = 0

    def wrap(self, place: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            previous = args[4] if len(args) > 4 else kwargs.get("previous")
            t0 = time.perf_counter()
            try:
                return place(*args, **kwargs)
            finally:
                dt = time.perf_counter() - t0
                self.calls += 1
                if previous is None:
                    self.cold += dt
                else:
                    self.warm += dt

        return timed


def main() -> None:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--grids", default="20")
    ap.add_argument("--surfaces", default="sphere-concave,bowl")
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    timer = Timer()
    # every module that calls place by its own name gets the timed one
    for module in list(sys.modules.values()):
        if getattr(module, "place", None) is placement.place and module is not placement:
            module.place = timer.wrap(placement.place)  # type: ignore[attr-defined]
    print(f"place() per warp, content {CONTENT[0]}x{CONTENT[1]}, mode content, one core")
    print(f"{'surface':15s} {'grid':>6} {'cold ms':>8} {'warm ms':>8} {'calls':>5} {'of warp':>8}")
    mask = subject_mask(*CONTENT)
    for name in args.surfaces.split(","):
        surface = simulate_surface(name, step=2)
        for g in args.grids.split(","):
            settings = WarpSettings(mode="content", grid=Grid(int(g), int(g)))
            compute_warp(surface, CONTENT, mask, settings)  # load code, libraries
            cold, warm, share, calls = [], [], [], 0
            for _ in range(args.repeat):
                timer.reset()
                t0 = time.perf_counter()
                compute_warp(surface, CONTENT, mask, settings)
                total = time.perf_counter() - t0
                cold.append(timer.cold)
                warm.append(timer.warm)
                share.append((timer.cold + timer.warm) / total)
                calls = timer.calls
            print(
                f"{name:15s} {g + 'x' + g:>6} {1e3 * statistics.median(cold):8.2f} "
                f"{1e3 * statistics.median(warm):8.2f} {calls:5d} "
                f"{100 * statistics.median(share):7.1f}%",
                flush=True,
            )


if __name__ == "__main__":
    main()
