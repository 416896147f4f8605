#!/usr/bin/env python3
"""What the warp's mesh costs, one core: against the whole warp, in the same run.

For each surface and grid (content mode, the off-centre subject of
``tools/bench_warp.py``), interleaved so that load from other jobs hits all alike:

* ``mesh cold`` - :func:`~adaproj_edge.warp.adaptive.adaptive_mesh` without a
  :class:`~adaproj_edge.warp.mesh.WarpCache` (sampling the surface, the crease pass,
  the topology, the bend test and any refinement), as a cold warp builds it;
* ``mesh cached`` - the same with a cache that has seen the scene;
* ``warp cold`` - :func:`~adaproj_edge.warp.planner.compute_warp` from scratch, whose
  share the mesh is.

Prints the best (least loaded) of ``--repeat`` blocks, as CPU time of this thread
(other jobs on the machine stretch wall time, not this), in ms per call.

    .venv/bin/python tools/bench_warp_mesh.py [--grids 20,40] [--repeat 15]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

from bench_warp import CONTENT, subject_mask  # (this directory is on the path)

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.adaptive import adaptive_mesh
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid


def block(call: Callable[[], object], calls: int) -> float:
    """CPU seconds of this thread per call, over ``calls`` calls."""
    t0 = time.thread_time()
    for _ in range(calls):
        call()
    return (time.thread_time() - t0) / calls


def measure(surface: Surface, grid: Grid, repeat: int) -> tuple[float, float, float]:
    """Seconds per call: the mesh cold, cached, and the cold warp (best of ``repeat``)."""
    mask = subject_mask(*CONTENT)
    settings = WarpSettings(mode="content", grid=grid)
    cache = WarpCache()
    adaptive_mesh(surface, grid, cache)  # the cache has seen the scene
    compute_warp(surface, CONTENT, mask, settings)  # load code, libraries
    cold, cached, warp = float("inf"), float("inf"), float("inf")
    for _ in range(repeat):  # interleaved: load from other jobs hits all three alike
        cold = min(cold, block(lambda: adaptive_mesh(surface, grid), 20))
        cached = min(cached, block(lambda: adaptive_mesh(surface, grid, cache), 20))
        warp = min(warp, block(lambda: compute_warp(surface, CONTENT, mask, settings), 2))
    return cold, cached, warp


def main() -> None:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--grids", default="20")
    ap.add_argument("--surfaces", default="sphere-concave,bowl")
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    print(f"{'surface':15s} {'grid':>6} {'mesh cold':>10} {'mesh cached':>12} {'warp cold':>10}")
    for name in args.surfaces.split(","):
        surface = simulate_surface(name, step=2)
        for g in args.grids.split(","):
            grid = Grid(int(g), int(g))
            cold, cached, warp = measure(surface, grid, args.repeat)
            print(
                f"{name:15s} {grid!s:>6} {1e3 * cold:9.2f}  {1e3 * cached:11.2f}  "
                f"{1e3 * warp:9.1f}   mesh {100 * cold / warp:.0f} % of the cold warp",
                flush=True,
            )


if __name__ == "__main__":
    main()
