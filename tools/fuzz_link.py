#!/usr/bin/env python3
"""Fuzz the link's frame decoder and SMP dispatcher with hypothesis, at length.

Eight targets from ``tests/link/fuzz_cases.py`` (the test suite runs a slice of each):

- ``wire``: byte streams (frames of malformed messages, mutated frames, stray
  delimiters, declared lengths up to 65535, noise) through ``FrameDecoder`` into the
  dispatcher; every decoded message's reply is checked and encoded back.
- ``dispatch``: one malformed message straight into ``Server.handle``.
- ``resync``: junk (stray partial frames, cut lines, noise with or without newlines),
  then one intact frame of a good request: it must be decoded and answered, whatever
  came before it (the decoder lives through the whole run, so every case also follows
  the junk of the one before).
- ``jpeg``: JPEGs with fill bytes before markers, bytes between segments, fake frame
  headers in comments: the size read from the header must be the decoder's, or the
  bytes are refused without decoding.
- ``refusals``: bursts of requests refused for distinct (group, command) pairs: the
  server's refusal log keeps at most its few reasons, whatever the burst.
- ``pending``: uploads begun and abandoned, declaring sizes that fill the quota: a
  whole new upload of another name still fits.
- ``state``: any JSON (or bytes) as the saved active record: a server on that store
  starts and answers.
- ``hangup``: a port whose host hangs up or stops reading at any point: ``serve``
  goes on and answers the last good request.

Every input must leave the server standing: no exception, a well-formed reply (same
group, sequence, command; op + 1) or nothing for what is not a request, never an
"internal error", decoder buffers within their bounds, no good frame lost after junk.
One server, store and decoder live through the whole run; hypothesis runs in batches
of ``--batch`` inputs (each with its own seed), so its own records of what it
generated are freed between batches. The process's resident memory after each batch
shows whether the server keeps anything: it must level off.

Usage::

    .venv/bin/python tools/fuzz_link.py [--examples 100000] [--batch 5000] [--seed 0]

``--examples`` is split evenly between the targets (``--targets`` picks some).
"""

from __future__ import annotations

import argparse
import gc
import logging
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.framing import FrameDecoder
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore, Limits
from adaproj_edge.threads import apply_thread_policy
from tests.link.fuzz_cases import (
    active_records,
    dispatch_target,
    hangup_target,
    hangups,
    jpeg_target,
    jpegs,
    messages,
    pending_floods,
    pending_target,
    refusal_bursts,
    refusals_target,
    resync_target,
    resyncs,
    state_target,
    streams,
    wire_target,
)
from tests.link.media import png_bytes

TARGETS = ("wire", "dispatch", "resync", "jpeg", "refusals", "pending", "state", "hangup")


def rss_mb() -> float:
    """Resident memory now (not the peak), from /proc."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class Target:
    """One fuzz target with its long-lived server, and what it has seen."""

    def __init__(self, name: str, root: Path) -> None:
        self.name = name
        self.root = root / name
        store = ContentStore(self.root, Limits(quota=2**20, max_file=2**19))
        self.server = Server(store, StandaloneDevice(64, 40), buf_size=2048)
        self.decoder = FrameDecoder(self.server.max_message)
        self.png = png_bytes(150, 100, seed=11)
        self.seen: Counter[str] = Counter()
        self.count = 0
        self.slowest = 0.0

    def timed(self, f: Callable[[], None]) -> None:
        t0 = time.perf_counter()
        f()
        self.slowest = max(self.slowest, time.perf_counter() - t0)
        self.count += 1

    def batch(self, n: int, batch_seed: int) -> None:
        config = settings(
            max_examples=n, deadline=None, database=None, suppress_health_check=list(HealthCheck)
        )
        strategies: dict[str, st.SearchStrategy[Any]] = {
            "wire": streams(),
            "dispatch": messages(),
            "resync": resyncs(),
            "jpeg": jpegs(),
            "refusals": refusal_bursts(),
            "pending": pending_floods(),
            "state": active_records,
            "hangup": hangups(),
        }
        run_one: dict[str, Callable[[Any], None]] = {
            "wire": lambda x: wire_target(self.server, self.decoder, x, self.seen),
            "dispatch": lambda x: dispatch_target(self.server, x, self.seen),
            "resync": lambda x: resync_target(self.server, self.decoder, x, self.seen),
            "jpeg": lambda x: jpeg_target(x, self.seen),
            "refusals": lambda x: refusals_target(self.server, x, self.seen),
            "pending": lambda x: pending_target(self.server, x, self.png, self.seen),
            "state": lambda x: state_target(self.root, x, self.seen),
            "hangup": lambda x: hangup_target(self.server, x, self.seen),
        }

        @seed(batch_seed)
        @config
        @given(strategies[self.name])
        def run(x: Any) -> None:
            self.timed(lambda: run_one[self.name](x))

        run()

    def summary(self) -> str:
        s, d = self.seen, self.decoder.stats
        if self.name not in ("wire", "dispatch", "resync"):
            return (
                f"{self.name}: {self.count} inputs; {dict(s)}; slowest input "
                f"{self.slowest * 1000:.1f} ms"
            )
        return (
            f"{self.name}: {self.count} inputs; replies: {s['success']} success, {s['error']} "
            f"SMP errors, {s['ignored']} ignored (not requests); frames decoded {d.frames}, "
            f"dropped {sum(d.dropped.values())} {dict(d.dropped)}; server counters "
            f"{self.server.counters}; good frames found after junk {s['resynchronised']}; "
            f"slowest input {self.slowest * 1000:.1f} ms"
        )


def main() -> int:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=100_000, help="inputs in all")
    ap.add_argument("--batch", type=int, default=5000, help="inputs per hypothesis run")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--targets", default=",".join(TARGETS), help=f"comma-separated, of {', '.join(TARGETS)}"
    )
    args = ap.parse_args()
    names = [t for t in args.targets.split(",") if t]
    unknown = set(names) - set(TARGETS)
    if unknown:
        raise SystemExit(f"unknown targets {sorted(unknown)}; known: {', '.join(TARGETS)}")
    logging.disable(logging.WARNING)  # every refusal is logged; millions of lines otherwise
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            target = Target(name, Path(tmp))
            want = args.examples // len(names)
            i = 0
            while target.count < want:
                before = target.count
                target.batch(min(args.batch, want - target.count), args.seed + i)
                i += 1
                if target.count == before:
                    raise SystemExit(f"{name}: hypothesis generated nothing new")
                gc.collect()
                print(f"  {name}: {target.count:>7d} inputs, RSS {rss_mb():6.1f} MB", flush=True)
            print(target.summary(), flush=True)
    print(f"total {args.examples} inputs in {time.monotonic() - t0:.0f} s, no failure")
    return 0


if __name__ == "__main__":
    sys.exit(main())
