#!/usr/bin/env python3
"""Benchmark the warp engine against the straightforward implementation, same run.

For each grid, ``content`` mode on the concave sphere with an off-centre subject mask:
initialisation (conformal + content-free solves and placement), time per alternation
step, and total, for the fast engine and for the straightforward one (the same energies
assembled term by term and solved with ``spsolve`` every iteration, as the paper
describes). Prints the times and their ratios; both run on one core.
"fast+cache" keeps the mesh topology and solver structures between calls
(``WarpCache``), as the device does while it looks at the same scene.

    .venv/bin/python tools/bench_warp.py [--grids 20,40,80] [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.engine import FAST, Backend, WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner, compute_warp
from adaproj_edge.warp.reference import REFERENCE
from adaproj_edge.warp.warpmap import Grid, Warp

CONTENT = (640, 400)


def subject_mask(w: int, h: int) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return (((xx - 0.3 * w) / (0.14 * w)) ** 2 + ((yy - 0.5 * h) / (0.3 * h)) ** 2 <= 1).astype(
        np.float32
    )


def run(
    backend: Backend, surface: object, grid: Grid, repeat: int, warm: bool = False
) -> tuple[dict[str, float], Warp]:
    mask = subject_mask(*CONTENT)
    settings = WarpSettings(mode="content", grid=grid)
    inits, steps, totals = [], [], []
    warp = None
    cache = WarpCache()
    if warm:
        compute_warp(surface, CONTENT, mask, settings, backend, cache)  # type: ignore[arg-type]
    for _ in range(repeat):
        c = cache if warm else None
        t0 = time.perf_counter()
        warp = compute_warp(surface, CONTENT, mask, settings, backend, c)  # type: ignore[arg-type]
        totals.append(time.perf_counter() - t0)
        # the stages, timed from outside (the engine reads no clock): the content-free
        # initialisation, then each content-aware step
        proj = surface.projector  # type: ignore[attr-defined]
        planner = WarpPlanner(proj, grid, PlanSettings(), c, backend)
        t0 = time.perf_counter()
        start = planner.content_free(surface, CONTENT, settings)  # type: ignore[arg-type]
        inits.append(time.perf_counter() - t0)
        marks = [time.perf_counter()]
        planner.refine(
            surface,  # type: ignore[arg-type]
            ContentMap(mask, CONTENT, settings.threshold),
            settings,
            start,
            on_step=lambda marks=marks: marks.append(time.perf_counter()),  # type: ignore[misc]
        )
        steps.extend(np.diff(marks).tolist())
    assert warp is not None
    return {
        "init": statistics.median(inits),
        "step": statistics.median(steps) if steps else float("nan"),
        "total": statistics.median(totals),
        "iterations": float(warp.meta["iterations"]),
    }, warp


def main() -> None:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--grids", default="20,40,80")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--surface", default="sphere-concave")
    args = ap.parse_args()
    surface = simulate_surface(args.surface, step=2)
    print(f"surface {args.surface}, content {CONTENT[0]}x{CONTENT[1]}, mode content, one core")
    print(f"{'grid':>7} {'':>10} {'init ms':>9} {'step ms':>9} {'total ms':>9} {'iters':>5}")
    for g in args.grids.split(","):
        grid = Grid(int(g), int(g))
        run(FAST, surface, grid, 1)  # load code and libraries
        cold, wf = run(FAST, surface, grid, args.repeat)
        warm, _ = run(FAST, surface, grid, args.repeat, warm=True)
        ref, wr = run(REFERENCE, surface, grid, max(1, args.repeat // 3))
        diff = float(np.nanmax(np.abs(wf.image_xy - wr.image_xy)))
        for name, r in (("reference", ref), ("fast", cold), ("fast+cache", warm)):
            print(
                f"{grid!s:>7} {name:>10} {1e3 * r['init']:9.1f} {1e3 * r['step']:9.2f} "
                f"{1e3 * r['total']:9.1f} {int(r['iterations']):5d}"
            )
        for name, r in (("ratio", cold), ("ratio+cache", warm)):
            print(
                f"{grid!s:>7} {name:>10} {ref['init'] / r['init']:8.1f}x "
                f"{ref['step'] / r['step']:8.1f}x {ref['total'] / r['total']:8.1f}x"
            )
        print(f"{grid!s:>7} max vertex difference fast vs reference: {diff:.1e} px")


if __name__ == "__main__":
    main()
