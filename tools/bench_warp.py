#!/usr/bin/env python3
"""Time to the final warp: the engine against the paper as written, same run, one core.

For each grid and doubly curved surface, ``content`` mode with an off-centre subject:

* ``paper ref`` - the paper as written, straightforwardly
  (:func:`adaproj_edge.warp.reference.paper_warp`: E_a, then E' with its auxiliary
  scales, the maximal inscribed rectangle, the alternation of eq. 8-9 assembled term by
  term and solved with ``spsolve`` every iteration, until the mean vertex motion is
  below 0.05 px or after 10 iterations); ``compute_warp(..., alternation="paper",
  backend=REFERENCE)``.
* ``ours cold`` - :func:`~adaproj_edge.warp.planner.compute_warp` from scratch (no
  :class:`~adaproj_edge.warp.mesh.WarpCache`: nothing of the scene is kept; what depends
  on the grid and the projector alone - the grid's rays and sampling stencil, its
  triangles - is made at the process's first warp and kept, as on the device).
* ``ours cached`` - the same with a :class:`~adaproj_edge.warp.mesh.WarpCache` that has
  seen the scene (mesh topology and solver structures kept, as the device does).

Prints the median time to the result, its iterations, and the ratios reference / ours
(target: >= 10x at 20x20 and 40x40), and the share of one cold ``compute_warp`` spent in
the guard and the crease analysis (``guard.guard`` and the meshes'
``creases.unfold_measured``, from cProfile runs timed by the process's CPU time, the
median of ``repeat // 2`` of them; target: <= 25 %). Then the new surfaces (relief,
waves, a curved crease) at the default grid, where the engine refines the mesh: their
time, the grid it used, and the guard's choice.

``--real`` adds the recorded real frames (``tests/fixtures/real/``): each region's
surface as the device path makes it from the raw depth (``tools/bench_real.py``).
``--surfaces`` takes the names of the built-in surfaces
(:data:`~adaproj_edge.geometry.analytic.SURFACES`), ``saddle`` (a hyperbolic paraboloid
``z = z0 - k (x^2 - y^2)``, made here) and ``all``: every surface class the quality
tests use (half cylinder on a floor, corner, cone meeting a wall, bumps, waves, the
spheres, the bowl) and the saddle.

    .venv/bin/python tools/bench_warp.py [--surfaces all] [--real] [--grids 20,40]
        [--repeat 5] [--cpu]

``--cpu`` times the CPU time of the thread instead of the wall clock: on a machine
shared with other jobs the wall clock counts the time the process waits for a core.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

# this tree's package, not whichever is installed (so that another checkout's copy of
# this tool times that checkout; bench_placement and bench_warp_mesh import this module)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.analytic import (
    FINE_DETAIL,
    _solve_quadratic,
    simulate_surface,
    single_patch,
)
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.engine import FAST, Backend, WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.reference import REFERENCE
from adaproj_edge.warp.warpmap import Grid, Warp

CONTENT = (640, 400)
# every surface class of the quality tests, and a saddle
ALL = (
    "cylinder-floor",
    "corner",
    "cone-wall",
    "bumps",
    "waves",
    "sphere-concave",
    "sphere-convex",
    "bowl",
    "saddle",
)


class Saddle:
    """A hyperbolic paraboloid ``z = z0 - k (x^2 - y^2)`` facing the projector (doubly
    curved with negative Gaussian curvature, which no built-in surface has)."""

    name = "saddle"
    developable = False
    grid_smooth = True

    def __init__(self, z0: float = 1.6, k: float = 0.6) -> None:
        self.z0, self.k = z0, k

    def patch(self, points: FloatArray) -> IntArray:
        """All 0: one smooth patch."""
        return single_patch(points)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the first hit with t > 0, NaN where none."""
        ox, oy, oz = origins[..., 0], origins[..., 1], origins[..., 2]
        dx, dy, dz = dirs[..., 0], dirs[..., 1], dirs[..., 2]
        a = self.k * (dx * dx - dy * dy)
        b = 2 * self.k * (ox * dx - oy * dy) + dz
        c = self.k * (ox * ox - oy * oy) + oz - self.z0
        return _solve_quadratic(a, b, c, far=False)


def bench_surface(name: str) -> Surface:
    """The surface called ``name`` (a built-in one or ``saddle``), at every 2nd pixel."""
    return simulate_surface(Saddle() if name == "saddle" else name, step=2)


def real_surfaces() -> list[tuple[str, Surface]]:
    """The surface the device path makes of each region of each recorded real frame
    (``tests/fixtures/real/``, as ``tools/bench_real.py`` runs them), named
    ``frame/region``; regions the device projects nothing on are left out."""
    from tests.realframes import FIXTURES, load_frames, run_device

    out = []
    for frame in load_frames(FIXTURES):
        for region in frame.regions:
            run = run_device(frame, region)
            if run.surface is not None and run.projected:
                out.append((f"{frame.name}/{region.name}", run.surface))
    return out


def guard_crease_share(surface: Surface, settings: WarpSettings) -> float:
    """The share of one cold ``compute_warp`` (cProfile, CPU time of the process) spent in
    ``guard.guard`` and in the meshes' crease analysis (``creases.unfold_measured``
    called by ``MeshGeometry.build``; the guard's own is counted in the guard's)."""
    mask = subject_mask(*CONTENT)
    prof = cProfile.Profile(time.process_time)
    t0 = time.process_time()
    prof.enable()
    compute_warp(surface, CONTENT, mask, settings)
    prof.disable()
    total = time.process_time() - t0
    stats: dict[Any, Any] = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    part = 0.0
    for (path, _, func), (_, _, _, cum, callers) in stats.items():
        if path.endswith("warp/guard.py") and func == "guard":
            part += cum
        elif path.endswith("geometry/creases.py") and func == "unfold_measured":
            for (cpath, _, cfunc), (_, _, _, ccum) in callers.items():
                if cpath.endswith("warp/mesh.py") and cfunc == "build":
                    part += ccum
    return part / max(total, 1e-12)


def subject_mask(w: int, h: int) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return (((xx - 0.3 * w) / (0.14 * w)) ** 2 + ((yy - 0.5 * h) / (0.3 * h)) ** 2 <= 1).astype(
        np.float32
    )


def timed(
    surface: Surface,
    settings: WarpSettings,
    backend: Backend,
    repeat: int,
    cache: WarpCache | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> tuple[float, Warp]:
    """Median seconds (by ``clock``) to the result over ``repeat`` runs, and the last
    warp."""
    mask = subject_mask(*CONTENT)
    times = []
    warp = None
    for _ in range(repeat):
        t0 = clock()
        warp = compute_warp(surface, CONTENT, mask, settings, backend, cache)
        times.append(clock() - t0)
    assert warp is not None
    return statistics.median(times), warp


def row(name: str, grid: Grid, label: str, seconds: float, warp: Warp) -> None:
    guard: dict[str, Any] = warp.meta.get("guard", {})
    print(
        f"{name:24s} {grid!s:>6} {label:>12} {1e3 * seconds:9.1f} "
        f"{int(warp.meta.get('iterations', 0)):5d}  {guard.get('choice', '')}",
        flush=True,
    )


def main() -> None:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--grids", default="20,40")
    ap.add_argument("--surfaces", default="sphere-concave,bowl", help="names, or all")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-new", action="store_true", help="skip the new surfaces")
    ap.add_argument("--cpu", action="store_true", help="CPU time of the thread, not wall")
    ap.add_argument(
        "--real",
        action="store_true",
        help="also the recorded real frames (tests/fixtures/real/), each region's surface "
        "as the device path makes it",
    )
    args = ap.parse_args()
    clock = time.thread_time if args.cpu else time.perf_counter
    what = "CPU time" if args.cpu else "wall clock"
    print(f"content {CONTENT[0]}x{CONTENT[1]}, mode content, off-centre subject, one core, {what}")
    print(f"{'surface':24s} {'grid':>6} {'':>12} {'ms':>9} {'iters':>5}")
    names = ALL if args.surfaces == "all" else tuple(args.surfaces.split(","))
    surfaces = [(name, bench_surface(name)) for name in names if name]
    if args.real:
        surfaces += real_surfaces()
    summary = []
    for name, surface in surfaces:
        for g in args.grids.split(","):
            grid = Grid(int(g), int(g))
            ours = WarpSettings(mode="content", grid=grid)
            paper = WarpSettings(mode="content", grid=grid, alternation="paper")
            compute_warp(surface, CONTENT, subject_mask(*CONTENT), ours)  # load code, libraries
            cache = WarpCache()
            timed(surface, ours, FAST, 1, cache, clock)  # the cache has seen the scene
            # interleaved, so that load from other jobs hits all three alike
            ref_t, cold_t, warm_t = [], [], []
            ref_warp: Warp | None = None
            for _ in range(max(1, args.repeat // 2)):
                try:  # (the paper as written has no answer for some real depth)
                    t, ref_warp = timed(surface, paper, REFERENCE, 1, None, clock)
                    ref_t.append(t)
                except (ValueError, AdaprojError) as e:
                    ref_t.append(float("nan"))
                    ref_error = f"{type(e).__name__}: {e}"
                t, cold_warp = timed(surface, ours, FAST, 2, None, clock)
                cold_t.append(t)
                t, warm_warp = timed(surface, ours, FAST, 2, cache, clock)
                warm_t.append(t)
            ref, cold, warm = (statistics.median(x) for x in (ref_t, cold_t, warm_t))
            if ref_warp is None:
                print(f"{name:24s} {grid!s:>6} {'paper ref':>12} failed: {ref_error}")
            else:
                row(name, grid, "paper ref", ref, ref_warp)
            row(name, grid, "ours cold", cold, cold_warp)
            row(name, grid, "ours cached", warm, warm_warp)
            # (the median of a few: one profiled run varies by a few points under load)
            share = statistics.median(
                guard_crease_share(surface, ours) for _ in range(max(1, args.repeat // 2))
            )
            print(
                f"{name:24s} {grid!s:>6} {'ratio':>12} {ref / cold:8.1f}x cold, "
                f"{ref / warm:.1f}x cached; guard + creases {100 * share:.0f} % of a cold warp",
                flush=True,
            )
            summary.append((name, grid, ref, cold, warm, share))
    print(
        f"\n{'surface':24s} {'grid':>6} {'ref ms':>8} {'cold ms':>8} {'cached':>8} "
        f"{'ratio':>7} {'cached':>7} {'guard+crease':>12}"
    )
    for name, grid, ref, cold, warm, share in summary:
        print(
            f"{name:24s} {grid!s:>6} {1e3 * ref:8.1f} {1e3 * cold:8.1f} {1e3 * warm:8.1f} "
            f"{ref / cold:6.1f}x {ref / warm:6.1f}x {100 * share:11.0f}%"
        )
    if args.no_new:
        return
    print("\nnew surfaces, default grid (the engine refines where the surface needs it):")
    for name in FINE_DETAIL:
        surface = simulate_surface(name, step=2)
        settings = WarpSettings(mode="content")
        compute_warp(surface, CONTENT, subject_mask(*CONTENT), settings)
        seconds, warp = timed(surface, settings, FAST, max(1, args.repeat // 2), None, clock)
        shape = warp.grid_uv.shape
        print(
            f"{name:24s} {'20x20':>6} {'ours cold':>12} {1e3 * seconds:9.1f} "
            f"{int(warp.meta.get('iterations', 0)):5d}  mesh {shape[1] - 1}x{shape[0] - 1} "
            f"{warp.meta.get('guard', {}).get('choice', '')}",
            flush=True,
        )


if __name__ == "__main__":
    main()
