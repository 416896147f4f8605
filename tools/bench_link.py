#!/usr/bin/env python3
"""Upload throughput over a pty: the advertised SMP buffer next to the default size.

``adaproj link`` runs in its own process on the master side of a pty pair, with its
content store in a temporary directory; this process uploads the same PNG through
``smpclient`` on the slave side, twice per round:

- ``advertised``: the client reads the server's MCUmgr parameters and fills its
  buffer (``--buf-size``, 32 KiB by default) with every request;
- ``default``: the client sizes requests as ``smpmgr`` does by default, two lines
  of 128 bytes (``BufferParams(128, 2)``), as any client does that ignores the
  parameters.

Every chunk is fsynced by the server before it is acknowledged, exactly as on the
device. Rounds alternate the two modes; the table gives the median.

Usage::

    .venv/bin/python tools/bench_link.py [--size-kb 512] [--rounds 3] [--buf-size 32768]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from smpclient import SMPClient
from smpclient.transport.serial import Auto, BufferParams, FragmentationStrategy, SMPSerialTransport

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link import client
from adaproj_edge.link.host_requests import FileUploadResumable


def test_png(size: int) -> bytes:
    """A PNG of about ``size`` bytes (noise does not compress)."""
    side = max(16, int((size / 3) ** 0.5))
    img = np.random.default_rng(0).integers(0, 256, (side, side, 3), dtype=np.uint8)
    return bytes(cv2.imencode(".png", img)[1].tobytes())


async def upload_once(
    port: str, strategy: FragmentationStrategy, data: bytes, name: str
) -> tuple[float, int, int]:
    """(seconds, requests, data bytes per request) for one upload with ``strategy``."""
    c = SMPClient(SMPSerialTransport(strategy), port, timeout_s=10.0)
    await c.connect()
    try:
        chunks = [0]
        t0 = time.perf_counter()
        await client.upload(
            c,
            data,
            name,
            lambda d, t: chunks.__setitem__(0, chunks[0] + 1),
            resume=False,
            timeout_s=10.0,
        )
        dt = time.perf_counter() - t0
        probe = FileUploadResumable(name=name, off=1, data=b"")
        return dt, chunks[0] - 1, c.get_max_cbor_and_data_size(probe)[1]
    finally:
        await c.disconnect()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size-kb", type=int, default=512, help="PNG size to upload")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--buf-size", type=int, default=32768, help="buffer the server advertises")
    args = ap.parse_args()
    data = test_png(args.size_kb * 1024)
    modes: dict[str, FragmentationStrategy] = {
        "advertised": Auto(),
        "default": BufferParams(line_length=128, line_buffers=2),
    }
    times: dict[str, list[float]] = {m: [] for m in modes}
    info: dict[str, tuple[int, int]] = {}
    with tempfile.TemporaryDirectory() as tmp, PtyPair.open() as pty:
        server = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "adaproj_edge.cli",
                "link",
                "--fd",
                str(pty.master),
                "--store",
                str(Path(tmp) / "store"),
                "--buf-size",
                str(args.buf_size),
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
            for r in range(args.rounds):
                for mode, strategy in modes.items():
                    dt, requests, size = asyncio.run(
                        upload_once(pty.path, strategy, data, f"bench-{mode}-{r}.png")
                    )
                    times[mode].append(dt)
                    info[mode] = (requests, size)
        finally:
            server.terminate()
            server.wait(10)
            if server.stderr is not None:
                server.stderr.close()
    print(f"upload of a {len(data)} B PNG over a pty, {args.rounds} rounds, median:")
    print(f"{'mode':<12}{'data B/req':>10}{'requests':>10}{'seconds':>10}{'KiB/s':>10}")
    rates = {}
    for mode in modes:
        t = statistics.median(times[mode])
        rates[mode] = len(data) / t / 1024
        requests, size = info[mode]
        print(f"{mode:<12}{size:>10}{requests:>10}{t:>10.3f}{rates[mode]:>10.1f}")
    ratio = rates["advertised"] / rates["default"]
    print(f"advertised buffer ({args.buf_size} B): {ratio:.1f}x the default-sized transfer")
    return 0


if __name__ == "__main__":
    sys.exit(main())
