#!/usr/bin/env python3
"""Benchmark the depth -> surface stage (``estimate_surface``) against the code it
replaced, in the same run.

Every depth frame of the committed sessions (cylinder, corner, sphere) goes through the
reference (``tests/geometry/test_depth_fast.py``: ``depth.py`` as it was before the speed-up,
the side-window fits on the whole supersampled lattice) and through
``adaproj_edge.geometry.depth.estimate_surface``, interleaved, on one core
(``apply_thread_policy(1)``: one BLAS and OpenCV thread). Prints median and p95 wall
time per frame in ms and the ratio, for the warp grid's lattice and a dense one.

    .venv/bin/python tools/bench_depth.py [--repeat 3] [--shapes 21x21,50x80]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # for tests.geometry.test_depth_fast (the reference)

from adaproj_edge.geometry.depth.estimate import estimate_surface  # noqa: E402
from adaproj_edge.session.reader import read_session  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from tests.geometry.test_depth_fast import ref_estimate_surface  # noqa: E402

SESSIONS = ("cylinder", "corner", "sphere")


def main() -> None:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="passes over all frames")
    ap.add_argument("--shapes", default="21x21,50x80", help="lattice shapes, rows x cols")
    args = ap.parse_args()
    # fill_holes (old and new alike) warns on holes without known neighbours yet
    warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
    frames = []
    for name in SESSIONS:
        session = read_session(ROOT / "tests" / "fixtures" / "sessions" / f"{name}.mcap")
        frames += [(session.calibration, rec.metres()) for rec in session.depth]
    print(f"{len(frames)} depth frames {frames[0][1].shape[::-1]}, {args.repeat} passes")
    print(f"{'lattice':>8} {'':>10} {'median ms':>10} {'p95 ms':>8}")
    for spec in args.shapes.split(","):
        rows, cols = (int(v) for v in spec.split("x"))
        times: dict[str, list[float]] = {"reference": [], "fast": []}
        for calibration, z in frames[:2]:  # warm up (imports, caches, allocations)
            estimate_surface(z, calibration, (rows, cols))
            ref_estimate_surface(z, calibration, (rows, cols))
        for _ in range(args.repeat):
            for calibration, z in frames:
                for label, fn in (("reference", ref_estimate_surface), ("fast", estimate_surface)):
                    t0 = time.perf_counter()
                    fn(z, calibration, (rows, cols))
                    times[label].append(1e3 * (time.perf_counter() - t0))
        med = {k: float(np.median(v)) for k, v in times.items()}
        for label, t in times.items():
            print(f"{spec:>8} {label:>10} {med[label]:10.2f} {np.percentile(t, 95):8.2f}")
        print(f"{spec:>8} {'ratio':>10} {med['reference'] / med['fast']:9.1f}x")


if __name__ == "__main__":
    main()
