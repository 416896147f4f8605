#!/usr/bin/env python3
"""Time ``adaproj warp`` and a short ``adaproj replay`` beside busy processes, with the
thread policy as a user gets it and pinned, and without the policy for reference.

Configurations, each a fresh ``adaproj`` process (``python -m adaproj_edge``):

- ``default``: the caller's environment without any thread variable (no
  ``OPENBLAS_NUM_THREADS``, no ``ADAPROJ_THREADS``): what a user or the service runs.
  The package's policy (``adaproj_edge/threads.py``) pins the libraries to one thread.
- ``pinned``: every thread variable set to 1 by the caller, as ``tools/test`` once did.
- ``unmanaged``: ``ADAPROJ_THREADS=auto`` (the libraries' own defaults: a thread per
  core), which is what every entry point did before the policy.

``--busy`` processes spin on the other cores meanwhile (a loaded device or machine).
Runs are interleaved (default, pinned, unmanaged, default, ...) so that a change of
load hits all three alike; the table gives the median wall time of each command, the
CPU time it used, and for ``warp`` the solve time it reports; the ratios are against
``pinned``, measured in the same run. Target: default / pinned <= 1.3.

    .venv/bin/python tools/bench_threads.py [--repeat 5] [--busy 1]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from adaproj_edge.content.builtin import poster
from adaproj_edge.fileio import write_png
from adaproj_edge.threads import LIBRARY_ENV, THREADS_ENV, apply_thread_policy

CONFIGS = ("default", "pinned", "unmanaged")


def environment(config: str) -> dict[str, str]:
    """The child's environment for one configuration."""
    env = {k: v for k, v in os.environ.items() if k not in LIBRARY_ENV and k != THREADS_ENV}
    if config == "pinned":
        env.update({name: "1" for name in LIBRARY_ENV})
        env[THREADS_ENV] = "1"
    elif config == "unmanaged":
        env[THREADS_ENV] = "auto"
    return env


def run_once(argv: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float, str]:
    """(wall s, CPU s, stdout) of one ``adaproj`` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "adaproj_edge", *argv],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"adaproj {argv[0]} failed:\n{proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stdout


def busy_processes(n: int) -> list[subprocess.Popen[bytes]]:
    """``n`` processes that keep a core busy until killed."""
    code = "while True: pass"
    return [subprocess.Popen([sys.executable, "-c", code]) for _ in range(n)]


def main() -> int:
    # this process computes nothing; each child gets the environment of its config
    apply_thread_policy(1)
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=5, help="runs of each command and config")
    ap.add_argument("--busy", type=int, default=1, help="competing busy processes")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        write_png(d / "poster.png", poster())
        warp = ["warp", "--surface", "sphere-convex", "--image", "poster.png", "--out", "w.npz"]
        commands = {"warp": warp, "replay": ["replay", "--no-score"]}
        results: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
        print(f"{os.cpu_count()} cores, {args.busy} busy process(es), {args.repeat} runs each")
        busy = busy_processes(args.busy)
        try:
            time.sleep(0.5)  # let them start spinning
            for k in range(args.repeat):
                for name, argv in commands.items():
                    for config in CONFIGS if k % 2 == 0 else CONFIGS[::-1]:
                        wall, cpu, out = run_once(argv, environment(config), d)
                        solve = json.loads(out)["time_s"] if name == "warp" else float("nan")
                        results.setdefault((name, config), []).append((wall, cpu, solve))
                print(f"  run {k + 1}/{args.repeat} done", file=sys.stderr)
        finally:
            for p in busy:
                p.kill()
                p.wait()
    print(
        f"{'command':8s} {'config':10s} {'wall s':>8s} {'cpu s':>8s} {'solve s':>8s} {'ratio':>7s}"
    )
    for name in commands:
        base = statistics.median(r[0] for r in results[(name, "pinned")])
        for config in CONFIGS:
            rows = results[(name, config)]
            wall = statistics.median(r[0] for r in rows)
            cpu = statistics.median(r[1] for r in rows)
            solve = statistics.median(r[2] for r in rows)
            print(f"{name:8s} {config:10s} {wall:8.2f} {cpu:8.2f} {solve:8.3f} {wall / base:6.2f}x")
    for name in commands:
        default = statistics.median(r[0] for r in results[(name, "default")])
        pinned = statistics.median(r[0] for r in results[(name, "pinned")])
        verdict = "ok" if default / pinned <= 1.3 else "over the target"
        print(f"{name}: default / pinned = {default / pinned:.2f} (target <= 1.3: {verdict})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
