"""``adaproj run --record``: the device loop records its inputs and the serial link's
traffic into one session, and the replay of that session gives the same link result.
No hardware: a scripted serial port (the rx bytes of a recorded push), a fake IMU and
button, an in-memory display, the real clock."""

from __future__ import annotations

import errno
import hashlib
import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.live import Device, _Source, run_loop
from adaproj_edge.app.replay import ReplayOptions, replay_session
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import MonotonicClock
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore
from adaproj_edge.session.reader import Scan, iter_records
from adaproj_edge.session.recorder import SessionTap
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.writer import SessionWriter
from tests.app.golden import PUSH_SESSION

CAL = Calibration.default()


class ScriptedPort:
    """Hands out ``chunks`` one per read, then times out; keeps what is written."""

    def __init__(self, chunks: list[bytes], replies: int) -> None:
        self.chunks = list(chunks)
        self.written: list[bytes] = []
        self.replies = replies
        self.done = threading.Event()

    def read(self, size: int, timeout: float) -> bytes:
        if self.chunks:
            return self.chunks.pop(0)
        time.sleep(min(timeout, 0.01))
        return b""

    def write(self, data: bytes) -> None:
        self.written.append(bytes(data))
        if len(self.written) >= self.replies:
            self.done.set()

    def close(self) -> None:
        pass


def _imu(clock: MonotonicClock) -> Callable[[], Any]:
    def read() -> ImuSample:
        time.sleep(0.005)
        t = clock.now_ns()
        return ImuSample(t, t, (0.0, -9.81, 0.0), (0.0, 0.0, 0.0))

    return read


def _button(clock: MonotonicClock) -> Callable[[], Any]:
    edges = [True, False]

    def read() -> ButtonEvent | None:
        time.sleep(0.05)
        if not edges:
            return None
        t = clock.now_ns()
        return ButtonEvent(t, t, 28, edges.pop(0))

    return read


def _push_traffic() -> tuple[list[bytes], list[bytes], dict[str, Any]]:
    scan = Scan()
    traffic = [r for r in iter_records(PUSH_SESSION, scan=scan) if isinstance(r, SerialTraffic)]
    rx = [r.data for r in traffic if r.direction == "rx"]
    tx = [r.data for r in traffic if r.direction == "tx"]
    return rx, tx, json.loads(scan.metadata["session"]["push"])


def test_run_records_inputs_and_serial_traffic_and_the_replay_agrees(tmp_path: Path) -> None:
    rx, tx, push = _push_traffic()
    clock = MonotonicClock()
    rt = Runtime(
        CAL,
        MemoryDisplay(CAL.projector.width, CAL.projector.height),
        clock,
        [builtin_item()],
        content_map_fn=mask_content_map,
    )
    server = Server(ContentStore(tmp_path / "store"), rt)
    port = ScriptedPort(rx, len(tx))
    session = tmp_path / "run.mcap"
    tap = SessionTap(SessionWriter(session, CAL, {"source": "test"}, clock.now_ns()), clock)
    sources = [
        _Source("imu", lambda: _imu(clock)),
        _Source("button", lambda: _button(clock)),
    ]
    stop = threading.Event()
    loop = threading.Thread(
        target=run_loop, args=(Device(rt, server, port, sources, clock, tap), stop)
    )
    loop.start()
    try:
        assert port.done.wait(20)
        deadline = time.monotonic() + 5
        while rt.item.name != push["name"] and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.2)
    finally:
        stop.set()
        loop.join(10)
    assert not loop.is_alive()
    # the live device took the push, as the recorded one did
    assert rt.item.name == push["name"]
    assert b"".join(port.written) == b"".join(tx)
    stored = (tmp_path / "store" / push["name"]).read_bytes()
    assert hashlib.sha256(stored).hexdigest() == push["sha256"]

    records = list(iter_records(session))
    serial = [r for r in records if isinstance(r, SerialTraffic)]
    assert b"".join(r.data for r in serial if r.direction == "rx") == b"".join(rx)
    assert b"".join(r.data for r in serial if r.direction == "tx") == b"".join(tx)
    assert sum(isinstance(r, ImuSample) for r in records) > 10
    assert [r.pressed for r in records if isinstance(r, ButtonEvent)] == [True, False]

    s = replay_session(session, tmp_path / "out", ReplayOptions(score=False))
    link = s["link"]
    assert link["requests"] == len(tx) and link["content_activations"] == 1
    assert link["tx_mismatches"] == 0
    assert [e["item"] for e in s["events"] if e["event"] == "content"] == [push["name"]]
    assert (tmp_path / "out" / "store" / push["name"]).read_bytes() == stored


def test_a_recording_that_fails_is_logged_and_does_not_stop_the_device(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    clock = MonotonicClock()
    writer = SessionWriter(tmp_path / "full.mcap", CAL, {}, clock.now_ns())

    def full(rec: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    writer.write = full  # type: ignore[method-assign]
    tap = SessionTap(writer, clock)
    tap.start()
    t = clock.now_ns()
    tap.add(ImuSample(t, t, (0.0, -9.81, 0.0), (0.0, 0.0, 0.0)))
    deadline = time.monotonic() + 5
    while tap.error is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert tap.error is not None and "No space left" in tap.error
    assert "No space left" in caplog.text
    tap.add(ImuSample(t, t, (0.0, -9.81, 0.0), (0.0, 0.0, 0.0)))  # ignored, no raise
    tap.close()
