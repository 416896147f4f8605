#!/usr/bin/env python3
"""The warp engine on random surfaces beyond the test set (issue 13).

Draws random members of every analytic surface class (``geometry/analytic.py``,
``geometry/relief.py``) within what a handheld projector 0.5-3 m from the surface
meets, random subject masks, modes, grids and content sizes, warps each with
:func:`~adaproj_edge.warp.planner.compute_warp` and scores the displayed per-pixel map
with the tests' independent scorer (``tests/distortion.py``: rays cast at the analytic
surface) against issue 13's lines:

* ``fold`` / ``cover`` / ``nonfinite``: zero folded triangles, content shown >= 0.9996,
  no inf anywhere and no NaN where the surface is (every case);
* ``worse``: content mode with a subject (our alternation) on a non-developable
  surface: the subject's angle error and size inconsistency each <= 1.0x the
  conformal warp's (same grid, same adaptive setting);
* ``exact``: developable surfaces smooth at the grid's scale, conformal and content
  mode: angle error and size std <= 3e-4; corrugations at least 2 grid cells long
  (adaptive grid on): <= 0.005. See :func:`exactness` for how "smooth at the grid's
  scale" is decided;
* ``crash``: any exception but a :class:`~adaproj_edge.errors.WarpError` /
  :class:`~adaproj_edge.errors.InputError` (those are reported as ``warperror``, for
  triage: the surface may truly not take the content).

Case ``i`` of seed ``s`` draws from ``numpy.random.default_rng([s, i])``, so one case is
reproduced alone by ``--seed s --case i``.

    .venv/bin/python tools/stress_warp.py --seed 1 --cases 100 [--start 0] [--case i]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.threads import apply_thread_policy
from tests.warp.random_surfaces import Case, Outcome, draw_case, run_case


def main() -> None:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cases", type=int, default=50)
    ap.add_argument("--start", type=int, default=0, help="first case index")
    ap.add_argument("--case", type=int, action="append", help="only these case indices")
    ap.add_argument("--kinds", default="", help="only these surface classes (comma-separated)")
    args = ap.parse_args()
    indices = args.case or list(range(args.start, args.start + args.cases))
    kinds = {k for k in args.kinds.split(",") if k}
    failed: list[tuple[Case, Outcome]] = []
    run = 0
    for i in indices:
        case = draw_case(args.seed, i)
        if kinds and case.kind not in kinds:
            continue
        out = run_case(case)
        run += 1
        status = "ok  " if not out.failures else "FAIL"
        figs = " ".join(
            f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
            for k, v in out.figures.items()
            if k in ("angle", "size", "angle_x", "size_x", "choice", "bend")
        )
        print(f"[{i:4d}] {status} {out.seconds:5.1f}s {case.describe()} | {figs}", flush=True)
        for f in out.failures:
            print(f"       {f}", flush=True)
        if out.failures:
            failed.append((case, out))
    print(f"\n{len(failed)} of {run} cases failed (seed {args.seed})")
    if failed:
        print(f"{'case':>5s}  {'surface':16s} {'failed':40s} reproduce")
        for case, out in failed:
            what = ",".join(f.split("(")[0] for f in out.failures)
            print(
                f"{case.index:5d}  {case.kind:16s} {what:40s} "
                f"nice -n 10 .venv/bin/python tools/stress_warp.py --seed {args.seed} "
                f"--case {case.index}"
            )


if __name__ == "__main__":
    main()
