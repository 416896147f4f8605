#!/usr/bin/env python3
"""Upload throughput over a pty: the advertised SMP buffer, after line noise, and the
default size.

``adaproj link`` runs in its own process on the master side of a pty pair, with its
content store in a temporary directory; this process uploads the same PNG through a
stock ``smpclient`` on the slave side, three times per round:

- ``clean``: the client reads the server's MCUmgr parameters and fills its buffer
  (``--buf-size``, 32 KiB by default) with every request;
- ``after noise``: the same, but first the line gets what a client that died
  mid-frame leaves on it (a start delimiter and part of a base64 line, no newline)
  and some random garbage. The device must resynchronise on the next frame start,
  so the client's parameters request is answered and the upload runs as the clean
  one does (before, the request was dropped and the client fell back to the
  default size);
- ``default``: the client sizes requests as ``smpmgr`` does by default, two lines
  of 128 bytes (``BufferParams(128, 2)``), as any client does that ignores the
  parameters (one round: it is about a hundred times slower).

Every chunk is fsynced by the server before it is acknowledged, exactly as on the
device; every upload ends with the device's SHA-256 of the file checked. Rounds
alternate the modes; the table gives the median, the ratios compare medians of the
same run. The device side and this client are one thread each (two processes, as a
device and a computer are).

Usage::

    .venv/bin/python tools/bench_link.py [--size-kb 512] [--rounds 5] [--buf-size 32768]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import asyncio
import itertools
import random
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import cv2
import numpy as np
from smpclient import SMPClient
from smpclient.transport.serial import Auto, BufferParams, FragmentationStrategy, SMPSerialTransport

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link import client
from adaproj_edge.link.framing import START
from adaproj_edge.link.host_requests import StatusRead
from adaproj_edge.threads import apply_thread_policy


def noise(seed: int) -> bytes:
    """Random garbage (newlines and all), then a stray partial frame with no newline."""
    rng = random.Random(seed)
    return bytes(rng.randrange(256) for _ in range(300)) + START + b"AAEAAgAD"[: 2 + seed % 6]


def test_png(size: int) -> bytes:
    """A PNG of about ``size`` bytes (noise does not compress)."""
    side = max(16, int((size / 3) ** 0.5))
    img = np.random.default_rng(0).integers(0, 256, (side, side, 3), dtype=np.uint8)
    return bytes(cv2.imencode(".png", img)[1].tobytes())


async def upload_once(
    port: str, strategy: FragmentationStrategy, data: bytes, name: str
) -> tuple[float, int, int]:
    """(seconds, requests, data bytes per request) for one upload with ``strategy``."""
    transport = SMPSerialTransport(strategy)
    c = SMPClient(transport, port, timeout_s=10.0)
    await c.connect()
    try:
        acked: list[int] = []
        t0 = time.perf_counter()
        await client.upload(c, data, name, lambda d, t: acked.append(d), resume=False)
        dt = time.perf_counter() - t0
        chunks = sum(1 for a, b in itertools.pairwise(acked) if b > a)
        return dt, chunks, int(transport.max_unencoded_size)
    finally:
        await c.disconnect()


async def device_link_status(port: str) -> dict[str, object]:
    """The device's link counters (what it dropped, what it refused)."""
    async with client.connect(port) as c:
        link: dict[str, object] = (await client.call(c, StatusRead())).link
        return link


def main() -> int:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size-kb", type=int, default=512, help="PNG size to upload")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of clean and after noise")
    ap.add_argument("--buf-size", type=int, default=32768, help="buffer the server advertises")
    args = ap.parse_args()
    data = test_png(args.size_kb * 1024)
    modes: dict[str, FragmentationStrategy] = {
        "clean": Auto(),
        "after noise": Auto(),
        "default": BufferParams(line_length=128, line_buffers=2),
    }
    times: dict[str, list[float]] = {m: [] for m in modes}
    info: dict[str, tuple[int, int]] = {}
    log: list[str] = []
    with tempfile.TemporaryDirectory() as tmp, PtyPair.open() as pty:
        server = subprocess.Popen(
            [
                *(sys.executable, "-m", "adaproj_edge.cli", "link"),
                *("--fd", str(pty.master), "--store", str(Path(tmp) / "store")),
                *("--buf-size", str(args.buf_size)),
            ],
            pass_fds=(pty.master,),
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert server.stderr is not None
            for line in server.stderr:
                if "SMP server up" in line:
                    break
            reader = threading.Thread(target=lambda: log.extend(server.stderr or []), daemon=True)
            reader.start()
            for r in range(args.rounds):
                for mode, strategy in modes.items():
                    if mode == "default" and r > 0:
                        continue  # ~100x slower: one round is enough to compare
                    if mode == "after noise":
                        os.write(pty.slave, noise(r))  # what a client that died leaves behind
                    dt, requests, size = asyncio.run(
                        upload_once(pty.path, strategy, data, f"bench-{r}-{mode[:5]}.png")
                    )
                    times[mode].append(dt)
                    info[mode] = (requests, size)
            status = asyncio.run(device_link_status(pty.path))
        finally:
            server.terminate()
            server.wait(10)
    print(f"upload of a {len(data)} B PNG over a pty, median of {args.rounds} rounds (default: 1):")
    print(f"{'mode':<12}{'msg B':>8}{'requests':>10}{'data B/req':>11}{'seconds':>9}{'KiB/s':>9}")
    rates = {}
    for mode in modes:
        t = statistics.median(times[mode])
        rates[mode] = len(data) / t / 1024
        requests, size = info[mode]
        per = len(data) / max(requests, 1)
        print(f"{mode:<12}{size:>8}{requests:>10}{per:>11.0f}{t:>9.3f}{rates[mode]:>9.1f}")
    after = rates["after noise"] / rates["clean"]
    requests = f"{info['clean'][0]} and {info['after noise'][0]} requests"
    print(f"after noise / clean: {after:.2f} ({requests})")
    ratio = rates["clean"] / rates["default"]
    print(f"advertised buffer ({args.buf_size} B): {ratio:.1f}x the default-sized transfer")
    warnings = sum("WARNING" in line for line in log)
    print(
        f"device: frames dropped {status.get('frames_dropped')}, requests refused "
        f"{status.get('errors')}, resume probes {status.get('probes')}; {warnings} warning "
        f"lines in its log for {args.rounds} noise bursts"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
