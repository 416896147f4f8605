#!/usr/bin/env python3
"""Fuzz the link's frame decoder and SMP dispatcher with hypothesis, at length.

Two targets from ``tests/link/fuzz_cases.py`` (the test suite runs a slice of each):

- ``wire``: byte streams (frames of malformed messages, mutated frames, stray
  delimiters, declared lengths up to 65535, noise) through ``FrameDecoder`` into the
  dispatcher; every decoded message's reply is checked and encoded back.
- ``dispatch``: one malformed message straight into ``Server.handle``.

Every input must leave the server standing: no exception, a well-formed reply (same
group, sequence, command; op + 1) or nothing for what is not a request, never an
"internal error", decoder buffers within their bounds. The run prints the counts, the
slowest single input, and the process's peak RSS at each quarter (bounded memory).

Usage::

    .venv/bin/python tools/fuzz_link.py [--examples 100000] [--seed 0]

``--examples`` is split evenly between the two targets.
"""

from __future__ import annotations

import argparse
import logging
import resource
import sys
import tempfile
import time
import tracemalloc
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from hypothesis import HealthCheck, given, seed, settings

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.framing import FrameDecoder
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore, Limits
from tests.link.fuzz_cases import dispatch_target, messages, streams, wire_target


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def ours_kb() -> float:
    """KiB held now by allocations made in adaproj_edge (the server, store, decoder)."""
    snap = tracemalloc.take_snapshot().filter_traces([tracemalloc.Filter(True, "*adaproj_edge*")])
    return sum(s.size for s in snap.statistics("filename")) / 1024


def run_target(name: str, n: int, rng_seed: int, root: Path) -> None:
    store = ContentStore(root / name, Limits(quota=2**20, max_file=2**19))
    server = Server(store, StandaloneDevice(64, 40), buf_size=2048)
    decoder = FrameDecoder(server.max_message)
    seen: Counter[str] = Counter()
    slowest = [0.0]
    count = [0]
    marks = {n * k // 4 for k in (1, 2, 3, 4)}

    def timed(f: Callable[[], None]) -> None:
        t0 = time.perf_counter()
        f()
        slowest[0] = max(slowest[0], time.perf_counter() - t0)
        count[0] += 1
        if count[0] in marks:
            print(
                f"  {name}: {count[0]:>7d} inputs, held by adaproj_edge {ours_kb():7.1f} KiB, "
                f"process peak RSS {peak_rss_mb():6.1f} MB (hypothesis's own records grow)",
                flush=True,
            )

    config = settings(
        max_examples=n,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    if name == "wire":

        @seed(rng_seed)
        @config
        @given(streams())
        def fuzz_wire(chunks: list[bytes]) -> None:
            timed(lambda: wire_target(server, decoder, chunks, seen))

        fuzz_wire()
    else:

        @seed(rng_seed)
        @config
        @given(messages())
        def fuzz_dispatch(message: bytes) -> None:
            timed(lambda: dispatch_target(server, message, seen))

        fuzz_dispatch()
    dropped = sum(decoder.stats.dropped.values())
    print(
        f"{name}: {count[0]} inputs; replies: {seen['success']} success, {seen['error']} "
        f"SMP errors, {seen['ignored']} ignored (not requests); frames decoded "
        f"{decoder.stats.frames}, dropped {dropped} {dict(decoder.stats.dropped)}; "
        f"server counters {server.counters}; slowest input {slowest[0] * 1000:.1f} ms"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=100_000, help="inputs in all")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    logging.disable(logging.WARNING)  # every refusal is logged; millions of lines otherwise
    tracemalloc.start(1)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("wire", "dispatch"):
            run_target(name, args.examples // 2, args.seed, Path(tmp))
    print(f"total {args.examples} inputs in {time.monotonic() - t0:.0f} s, no failure")
    return 0


if __name__ == "__main__":
    sys.exit(main())
