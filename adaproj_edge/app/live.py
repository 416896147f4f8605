"""The runtime on the board: one reader thread per device feeding one queue, the
runtime on the main thread, the SMP server on a thread of its own.

A device that fails is reported to the runtime (status mark) and opened again every
``retry_s``; the projector keeps the last good frame meanwhile.

With a :class:`~adaproj_edge.session.recorder.SessionTap` (``adaproj run --record``)
every input handed to the runtime and the link's traffic are recorded into one
session, which ``adaproj replay`` plays back through the same runtime and server.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from adaproj_edge.app.content import builtin_item
from adaproj_edge.app.inputs import RECORDED, Input, SourceFault, feed
from adaproj_edge.app.memory import pin_mmap_threshold
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.errors import AdaprojError, DeviceError
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.button import EvdevButton
from adaproj_edge.hal.clock import Clock, MonotonicClock
from adaproj_edge.hal.depth import OakDepthCamera
from adaproj_edge.hal.display import FramebufferDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.hal.lsm6dsox import Lsm6dsox, open_i2c
from adaproj_edge.hal.serial import PySerialPort, SerialPort
from adaproj_edge.link.server import Server, serve
from adaproj_edge.link.store import ContentStore
from adaproj_edge.session.recorder import SessionTap
from adaproj_edge.session.writer import SessionWriter

log = logging.getLogger(__name__)

Reader = Callable[[], Input | None]


@dataclass
class _Source:
    """A device read in its own thread: ``open`` (re)creates the reader."""

    name: str
    open: Callable[[], Reader]


def _pump(
    src: _Source,
    out: queue.Queue[Input],
    stop: threading.Event,
    clock: Clock,
    retry_s: float,
) -> None:
    read: Reader | None = None
    while not stop.is_set():
        try:
            if read is None:
                read = src.open()
                log.info("%s open", src.name)
            item = read()
            if item is not None:
                out.put(item)
        except AdaprojError as e:
            out.put(SourceFault(src.name, str(e)))
            read = None
            clock.sleep_until(clock.now_ns() + int(retry_s * 1e9))


@dataclass
class Device:
    """What :func:`run_loop` runs: the runtime, the link (server and port, ``None``
    without a link), the input sources, and optionally a session being recorded."""

    runtime: Runtime
    server: Server
    port: SerialPort | None
    sources: list[_Source]
    clock: Clock
    tap: SessionTap | None = None


def run_loop(device: Device, stop: threading.Event | None = None, retry_s: float = 1.0) -> None:
    """Boot, start a thread per source and one for the link, and feed the runtime on
    this thread until ``stop`` is set (or an interrupt); the recording is closed last."""
    stop = stop or threading.Event()
    runtime, server, tap = device.runtime, device.server, device.tap
    inputs: queue.Queue[Input] = queue.Queue(maxsize=256)
    threads = [
        threading.Thread(
            target=_pump,
            args=(src, inputs, stop, device.clock, retry_s),
            daemon=True,
            name=src.name,
        )
        for src in device.sources
    ]
    link = None
    if device.port is not None:
        port = tap.port(device.port) if tap is not None else device.port
        link = threading.Thread(target=serve, args=(port, server, stop), daemon=True, name="link")
        threads.append(link)
    runtime.boot()
    server.restore_active()
    if tap is not None:
        tap.start()
    for t in threads:
        t.start()
    try:
        while not stop.is_set():
            try:
                item = inputs.get(timeout=0.02)
            except queue.Empty:
                runtime.tick()
                continue
            runtime.tick()
            if tap is not None and isinstance(item, RECORDED):
                tap.add(item)
            feed(runtime, item)
    finally:
        stop.set()
        if tap is not None:
            if link is not None:
                link.join(timeout=1.0)  # its last reply goes into the recording
            n = tap.close()
            log.info("recorded %d records to %s", n, tap.writer.path)


def run_device(
    board: Board,
    store_dir: Path,
    state_dir: Path | None = None,
    settings: AppSettings | None = None,
    retry_s: float = 1.0,
    record: Path | None = None,
) -> None:
    """Run the projector until interrupted (Ctrl-C / SIGTERM as KeyboardInterrupt);
    with ``record``, record a session of the run (inputs and serial traffic)."""
    pin_mmap_threshold()
    clock = MonotonicClock()
    calibration = board.calibration()
    display = FramebufferDisplay(board.display_device)
    runtime = Runtime(calibration, display, clock, [builtin_item()], settings, state_dir=state_dir)

    def open_imu() -> Reader:
        bus = open_i2c(board.imu.bus)
        imu = Lsm6dsox(bus, clock, board.imu.address, board.imu.config, f"/dev/i2c-{board.imu.bus}")
        imu.start()

        def read() -> ImuSample | None:
            s = imu.read()
            if s is None:
                clock.sleep_until(clock.now_ns() + int(0.5e9 / board.imu.config.rate_hz))
            return s

        return read

    def open_depth() -> Reader:
        return OakDepthCamera(board.depth, clock).read

    def open_button() -> Reader:
        button = EvdevButton(board.button_device, board.key_code, clock)
        return lambda: button.read(0.1)

    sources = [
        _Source("imu", open_imu),
        _Source("depth", open_depth),
        _Source("button", open_button),
    ]
    server = Server(ContentStore(store_dir), runtime)
    server.on_reset = server.restore_active
    port: SerialPort | None = None
    try:
        port = PySerialPort(board.serial_device)
    except DeviceError as e:
        log.error("no serial link (%s); running without content updates", e)
    tap = None
    try:
        if record is not None:
            meta = {"source": "device", "board": board.name, "command": "run"}
            tap = SessionTap(SessionWriter(record, calibration, meta, clock.now_ns()), clock)
            log.info("recording to %s", record)
        run_loop(Device(runtime, server, port, sources, clock, tap), retry_s=retry_s)
    finally:
        display.close()
