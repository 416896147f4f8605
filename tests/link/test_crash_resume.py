"""Kill the server at random points during uploads; nothing committed is ever bad.

Each upload is cut by SIGKILL to ``adaproj link`` at a random point (a random offset,
plus a random delay so the kill lands anywhere: mid-write, mid-fsync, mid-commit).
With the server dead, every committed file must be byte-identical to a whole upload
and the active record must still name the untouched original. After a restart, the
device shows the old content again and the upload resumes to a byte-exact file.

The CI run makes a few uploads; ``ADAPROJ_LINK_CRASH_UPLOADS=100`` makes the full run.
"""

from __future__ import annotations

import asyncio
import os
import random
import threading
from collections import Counter
from pathlib import Path

from adaproj_edge.errors import LinkError
from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link import client
from adaproj_edge.link.host_requests import ActivateWrite, StatusRead
from tests.link.media import png_bytes
from tests.link.process import LinkProcess

UPLOADS = int(os.environ.get("ADAPROJ_LINK_CRASH_UPLOADS", "5"))


def _killer(
    cut: int, delay: float, link: LinkProcess, timers: list[threading.Timer]
) -> client.Progress:
    """A progress callback that kills the server ``delay`` s after ``cut`` bytes are acked."""

    def progress(done: int, total: int) -> None:
        if done >= cut and not timers:
            timers.append(threading.Timer(delay, link.kill))
            timers[0].start()

    return progress


def committed(store: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in store.iterdir() if p.is_file() and p.name[0] != "."}


async def _upload(port: str, data: bytes, name: str, on_progress: client.Progress) -> int:
    async with client.connect(port, timeout_s=1.0) as c:
        return await client.upload(c, data, name, on_progress, timeout_s=1.0, tries=1)


async def _resume_and_check(port: str, data: bytes, name: str) -> tuple[int, dict[str, object]]:
    async with client.connect(port, timeout_s=5.0) as c:
        start = await client.upload(c, data, name)
        status = await client.call(c, StatusRead())
        return start, status.device


def run_campaign(uploads: int, root: Path, seed: int = 1) -> Counter[str]:
    """Run ``uploads`` killed uploads; assert the guarantees; count the outcomes."""
    rng = random.Random(seed)
    store = root / "store"
    outcomes: Counter[str] = Counter()
    shown = png_bytes(96, 64, seed=1000)
    expected = {"shown.png": shown}
    with PtyPair.open() as pty, open(root / "link.log", "w") as log:
        link = LinkProcess(pty, store, log, "--buf-size", "4096")
        link.start()
        try:
            asyncio.run(_resume_and_check(pty.path, shown, "shown.png"))
            with_activate = ActivateWrite(image="shown.png")

            async def activate() -> None:
                async with client.connect(pty.path) as c:
                    await client.call(c, with_activate)

            asyncio.run(activate())
            for i in range(uploads):
                w = rng.randint(80, 240)
                data = png_bytes(w, rng.randint(60, 180), seed=i)
                name = f"u{i:03d}.png"
                expected[name] = data
                cut = rng.randrange(len(data))
                delay = rng.uniform(0.0, 0.03)
                timers: list[threading.Timer] = []
                progress = _killer(cut, delay, link, timers)

                try:
                    asyncio.run(_upload(pty.path, data, name, progress))
                    outcomes["finished before the kill"] += 1
                except LinkError:
                    outcomes["cut"] += 1
                for t in timers:
                    t.join()
                link.wait_dead()

                # the server is dead: what is committed must be whole, the active untouched
                for item, content in committed(store).items():
                    assert content == expected[item], f"{item} is corrupt after a kill"
                active = (store / ".active.json").read_text()
                assert '"image": "shown.png"' in active
                assert (store / "shown.png").read_bytes() == shown

                link.start()
                start, device = asyncio.run(_resume_and_check(pty.path, data, name))
                assert device["state"] == "showing" and device["image"] == "shown.png"
                assert (store / name).read_bytes() == data, f"{name} not byte-exact after resume"
                if start == len(data):
                    outcomes["already committed at the kill"] += 1
                elif start > 0:
                    outcomes["resumed mid-way"] += 1
                else:
                    outcomes["restarted from 0 (killed before the first ack)"] += 1
            assert not list((store / ".incoming").iterdir())
        finally:
            link.wait_dead()
    return outcomes


def test_kills_during_uploads_never_corrupt_and_always_resume(tmp_path: Path) -> None:
    outcomes = run_campaign(UPLOADS, tmp_path)
    print(f"{UPLOADS} uploads killed at random points: {dict(outcomes)}")
    attempts = outcomes["cut"] + outcomes["finished before the kill"]
    assert attempts == UPLOADS and outcomes.total() == 2 * UPLOADS
