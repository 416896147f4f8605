"""Real clients over a real pty with noise on the line: stray partial frames, garbage,
corrupted bytes, in both directions.

What must hold: a stray frame costs the next client nothing (it still learns the
device's buffer, so an upload after the noise runs at the clean rate: compared by
requests and bytes per request, measured in the same test, never by the clock), and
``adaproj push`` through corrupted bytes finishes by itself, byte-exact, saying what
happened in short lines of its own.
"""

from __future__ import annotations

import asyncio
import io
import os
import random
import statistics
from pathlib import Path

import pytest
from smpclient import SMPClient
from smpclient.transport.serial import SMPSerialTransport

from adaproj_edge import cli
from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link import client
from adaproj_edge.link.framing import CONTINUE, START, encode_frame
from tests.link.conftest import NoisyLine
from tests.link.media import png_bytes
from tests.link.noise import Damage
from tests.link.process import LinkProcess
from tests.link.test_pty_clients import smpmgr

BUF = 4096  # the fixture server's buffer


def _garbage(n: int, seed: int, *, lines: bool) -> bytes:
    """Random bytes; with ``lines`` any byte, else none of newline and the delimiters'
    first bytes (noise inside one line)."""
    rng = random.Random(seed)
    alphabet = range(256) if lines else [b for b in range(256) if b not in b"\n\x06\x04"]
    return bytes(rng.choice(alphabet) for _ in range(n))


STRAYS = {
    "partial first line": START + b"AAAAB",
    "partial frame": b"".join(encode_frame(os.urandom(3000)).split(b"\n")[:2]) + b"\n",
    "garbage": _garbage(400, 1, lines=True),
    "garbage then a partial line": _garbage(200, 2, lines=False) + START + b"QUJD",
    "lost newline": START + b"AAAA" + CONTINUE + b"QUJD",
}


async def stock_upload(path: str, data: bytes, name: str) -> int:
    """Upload with a stock ``smpclient`` (Auto sizing, as any client); its message size."""
    transport = SMPSerialTransport()
    c = SMPClient(transport, path, timeout_s=5.0)
    await c.connect()
    try:
        await client.upload(c, data, name, resume=False, tries=1)
        return int(transport.max_unencoded_size)
    finally:
        await c.disconnect()


@pytest.mark.parametrize("stray", sorted(STRAYS))
def test_a_stray_frame_costs_the_next_client_nothing(line: NoisyLine, stray: str) -> None:
    data = png_bytes(160, 120, seed=3)
    before = line.requests()
    clean_size = asyncio.run(stock_upload(line.pty.path, data, "clean.png"))
    clean = line.requests() - before

    os.write(line.pty.slave, STRAYS[stray])  # left on the line by a client that died
    before = line.requests()
    noisy_size = asyncio.run(stock_upload(line.pty.path, data, "after.png"))
    noisy = line.requests() - before

    assert clean_size == BUF - 4  # the clean client learnt the buffer
    assert noisy_size == clean_size, "the parameters request after the noise was lost"
    assert clean / noisy >= 0.9  # the same round trips: the same rate
    assert (line.server.store.root / "after.png").read_bytes() == data


def test_smpmgr_after_a_stray_frame_gets_every_request_answered(
    line: NoisyLine, tmp_path: Path
) -> None:
    data = png_bytes(90, 60, seed=4)
    src = tmp_path / "src.png"
    src.write_bytes(data)
    counts = []
    for name in ("clean.png", "after.png"):
        if counts:
            os.write(line.pty.slave, STRAYS["partial first line"])
        before = line.requests()
        up = smpmgr(line.pty.path, "file", "upload", str(src), f"/{name}")
        assert up.returncode == 0, up.stderr + up.stdout
        counts.append(line.requests() - before)
    assert counts[1] == counts[0]  # the parameters request after the stray frame included
    assert (line.server.store.root / "after.png").read_bytes() == data
    assert line.server.decoder.stats.dropped == {"line cut short": 1}


# frames in each direction: 1 parameters, 2 upload state, 3 file status, 4... chunks
NOISE = {
    "corrupted chunk": {"to_device": [Damage(6, flip_at=300)]},
    "corrupted reply": {"to_host": [Damage(6, flip_at=4)]},
    "corrupted parameters request": {"to_device": [Damage(1, flip_at=4)]},
    "corrupted parameters reply": {"to_host": [Damage(1, flip_at=4)]},
    "stray partial reply": {"to_host": [Damage(7, before=START + b"AAAAB")]},
    "three hits": {
        "to_device": [Damage(5, flip_at=100), Damage(8, flip_at=900)],
        "to_host": [Damage(11, flip_at=4)],
    },
    "garbage before a chunk": {"to_device": [Damage(6, before=_garbage(300, 5, lines=False))]},
}


@pytest.mark.parametrize("noise", sorted(NOISE))
def test_push_through_noise_finishes_by_itself(
    line: NoisyLine, tmp_path: Path, capsys: pytest.CaptureFixture[str], noise: str
) -> None:
    clean_src, src = tmp_path / "clean.png", tmp_path / "photo.png"
    clean_src.write_bytes(png_bytes(150, 110, seed=11))
    data = png_bytes(150, 110, seed=12)
    src.write_bytes(data)
    args = ["--port", line.pty.path, "--timeout", "1"]
    assert cli.main(["push", str(clean_src), *args]) == 0
    clean = list(line.uploads)
    capsys.readouterr()

    line.uploads.clear()
    line.port.rx.plan = list(NOISE[noise].get("to_device", []))
    line.port.tx.plan = list(NOISE[noise].get("to_host", []))
    line.port.rx.frames = line.port.tx.frames = 0
    before = line.requests() + line.server.counters["ignored"]
    assert cli.main(["push", str(src), "--activate", *args]) == 0
    answered = line.requests() + line.server.counters["ignored"] - before
    out, err = capsys.readouterr()

    assert (line.server.store.root / "photo.png").read_bytes() == data
    assert "showing photo.png" in out
    assert not line.port.rx.plan and not line.port.tx.plan, "the noise did not happen"
    assert line.port.rx.done + line.port.tx.done
    # after the noise the chunks still fill the device's buffer
    assert statistics.median(line.uploads) >= 0.9 * statistics.median(clean)
    lines = err.splitlines()
    assert all(len(x) < 400 for x in lines), "a dump on stderr"
    notes = [x for x in lines if "reconnecting" in x or "again" in x]
    assert all("\r" not in x for x in notes), "a message glued onto the progress bar"
    if noise == "garbage before a chunk":
        assert answered == line.port.rx.frames  # the device lost no frame to the garbage
    elif "parameters" not in noise:  # (a lost hello is asked again, quietly)
        assert notes and all(x.startswith("photo.png: ") for x in notes)


def test_after_noise_an_upload_runs_at_the_clean_rate(line: NoisyLine) -> None:
    """One session: a clean upload, one through noise (a chunk lost, then the reply to
    the parameters request of the reconnect garbled), and one after: it must send as
    many chunks, each as full, as the clean one. (Upload requests, not all requests:
    a reply slower than the timeout on a loaded machine adds a resync, not a chunk.)"""
    plans = [[], [Damage(5, flip_at=300)], []]
    replies = [[], [Damage(5, flip_at=4)], []]
    sizes: list[float] = []
    counts: list[int] = []
    notes: list[str] = []

    async def go() -> None:
        async with client.connect(line.pty.path, timeout_s=1.0) as c:
            for i, (plan, reply) in enumerate(zip(plans, replies, strict=True)):
                line.port.rx.plan, line.port.rx.frames = list(plan), 0
                line.port.tx.plan, line.port.tx.frames = list(reply), 0
                line.uploads.clear()
                data = png_bytes(150, 110, seed=20 + i)
                await client.upload(c, data, f"p{i}.png", timeout_s=1.0, notify=notes.append)
                assert (line.server.store.root / f"p{i}.png").read_bytes() == data
                counts.append(len(line.uploads))
                sizes.append(statistics.mean(line.uploads))
            # at connect, at the resync, and again when the reply to that one was garbled
            assert c.hellos >= 3 and c.buf_size == BUF

    asyncio.run(go())
    assert len(line.port.rx.done) == 1 and len(line.port.tx.done) == 1
    assert "no answer" in notes[0] and "going on" in notes[1]
    assert counts[0] / counts[2] >= 0.9 and sizes[2] >= 0.9 * sizes[0]


def test_smpmgr_upload_through_garbage_between_frames(line: NoisyLine, tmp_path: Path) -> None:
    """A stock client has no retries: the device must not lose a frame to garbage."""
    data = png_bytes(90, 60, seed=6)
    src = tmp_path / "src.png"
    src.write_bytes(data)
    line.port.rx.plan = [Damage(k, before=_garbage(100, k, lines=False)) for k in (2, 5, 9)]
    up = smpmgr(line.pty.path, "file", "upload", str(src), "/g.png")
    assert up.returncode == 0, up.stderr + up.stdout
    assert len(line.port.rx.done) == 3
    assert (line.server.store.root / "g.png").read_bytes() == data


def test_adaproj_link_process_resynchronises(tmp_path: Path) -> None:
    """``adaproj link`` in its own process: a stray frame, then a stock client."""
    data = png_bytes(100, 80, seed=7)
    log = io.StringIO()
    with PtyPair.open() as pty:
        link = LinkProcess(pty, tmp_path / "store", log, "--buf-size", "4096")
        link.start()
        try:
            os.write(pty.slave, STRAYS["garbage then a partial line"])
            size = asyncio.run(stock_upload(pty.path, data, "x.png"))
        finally:
            link.wait_dead()
    assert size == 4096 - 4  # the parameters request after the stray frame was answered
    assert (tmp_path / "store" / "x.png").read_bytes() == data
    assert log.getvalue().count("WARNING") == 1  # the stray frame, once
