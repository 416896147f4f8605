"""The runtime on the board: one reader thread per device feeding one queue, the
runtime on the main thread, the SMP server on a thread of its own, and the display
thread (:func:`~adaproj_edge.app.display_loop.run_display`), which owns the projector:
it waits for each refresh and shows the last frame the runtime rendered, stabilised
with the gyro. The IMU's reader hands every sample to the display loop directly (the
runtime's queue would hold it back while a depth frame is processed) as well as to
the queue.

A device that fails is reported to the runtime (status mark), closed, and opened again
every ``retry_s``; the projector keeps the last good frame meanwhile.

The hold gesture (calibration) stops the reader threads, which close their devices,
and hands the board to :func:`~adaproj_edge.app.calibration_run.calibrate_device` on
the main thread (the link goes on serving); the readers start again afterwards.

With a :class:`~adaproj_edge.session.recorder.SessionTap` (``adaproj run --record``)
every input handed to the runtime and the link's traffic are recorded into one
session, which ``adaproj replay`` plays back through the same runtime and server.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Protocol, TypeVar

from adaproj_edge.app.content import builtin_item
from adaproj_edge.app.display_loop import run_display
from adaproj_edge.app.inputs import RECORDED, Input, SourceFault, feed
from adaproj_edge.app.memory import pin_mmap_threshold
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.errors import AdaprojError, DeviceError
from adaproj_edge.geometry.calibration import Calibration
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
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.render.photometry import PhotometrySettings
from adaproj_edge.session.recorder import SessionTap
from adaproj_edge.session.writer import SessionWriter

log = logging.getLogger(__name__)

Reader = Callable[[], Input | None]
Calibrate = Callable[[], tuple[Calibration | None, str]]
MeasureColour = Callable[[], tuple[Measured | None, str]]


class _Closable(Protocol):
    def close(self) -> None: ...


_C = TypeVar("_C", bound=_Closable)


class _Held:
    """The device a source has open now (so that it can be closed when its reader
    fails or its thread stops)."""

    def __init__(self) -> None:
        self.device: _Closable | None = None

    def keep(self, device: _C) -> _C:
        self.device = device
        return device

    def close(self) -> None:
        device, self.device = self.device, None
        if device is not None:
            device.close()


def _leave_open() -> None:
    pass


@dataclass
class _Source:
    """A device read in its own thread: ``open`` (re)creates the reader, ``close``
    closes what it opened."""

    name: str
    open: Callable[[], Reader]
    close: Callable[[], None] = _leave_open


def _pump(
    src: _Source,
    out: queue.Queue[Input],
    stop: threading.Event,
    clock: Clock,
    retry_s: float,
) -> None:
    read: Reader | None = None
    try:
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
                _close(src)
                clock.sleep_until(clock.now_ns() + int(retry_s * 1e9))
    finally:
        _close(src)


def _close(src: _Source) -> None:
    try:
        src.close()
    except AdaprojError as e:
        log.warning("closing the %s: %s", src.name, e)


@dataclass
class Device:
    """What :func:`run_loop` runs: the runtime, the link (server and port, ``None``
    without a link), the input sources, optionally a session being recorded, the
    calibration the hold gesture runs (``None``: the gesture is answered "no
    calibration on this device"), and whether a display thread shows the runtime's
    frames at each refresh (otherwise the runtime shows each frame as it renders it)."""

    runtime: Runtime
    server: Server
    port: SerialPort | None
    sources: list[_Source]
    clock: Clock
    tap: SessionTap | None = None
    calibrate: Calibrate | None = field(default=None)
    refresh: bool = False
    measure_colour: MeasureColour | None = field(default=None)


class _Readers:
    """The source threads and the display thread, stopped and started again around a
    calibration (which shows its own patterns on the projector)."""

    def __init__(self, device: Device, out: queue.Queue[Input], retry_s: float) -> None:
        self.device, self.out, self.retry_s = device, out, retry_s
        self.halt = threading.Event()
        self.threads: list[threading.Thread] = []

    def start(self) -> None:
        self.halt = threading.Event()
        self.threads = [
            threading.Thread(
                target=_pump,
                args=(src, self.out, self.halt, self.device.clock, self.retry_s),
                daemon=True,
                name=src.name,
            )
            for src in self.device.sources
        ]
        if self.device.refresh:
            self.threads.append(
                threading.Thread(
                    target=run_display,
                    args=(self.device.runtime.screen, self.device.clock, self.halt),
                    daemon=True,
                    name="display",
                )
            )
        for t in self.threads:
            t.start()

    def pause(self, timeout_s: float = 5.0) -> None:
        """Stop the threads (they close their devices); what they read is dropped."""
        self.halt.set()
        clock = self.device.clock
        deadline = clock.now_ns() + int(timeout_s * 1e9)
        for t in self.threads:
            while t.is_alive() and clock.now_ns() < deadline:
                _drain(self.out)  # a reader blocked on a full queue gets to stop
                t.join(timeout=0.05)
            if t.is_alive():
                log.warning("the %s reader did not stop within %g s", t.name, timeout_s)
        _drain(self.out)


def _drain(q: queue.Queue[Input]) -> None:
    while True:
        try:
            q.get_nowait()
        except queue.Empty:
            return


def _calibrate(device: Device, readers: _Readers) -> None:
    """The hold gesture: readers stopped, the calibration run, the runtime told."""
    runtime = device.runtime
    if device.calibrate is None:
        runtime.recalibrate(None, "no calibration on this device")
        return
    log.info("calibration asked for: stopping the depth camera and IMU readers")
    readers.pause()  # what they read before is stale after the calibration
    try:
        calibration, message = device.calibrate()
        log.info("calibration: %s", message)
        try:
            runtime.recalibrate(calibration, message)
        except AdaprojError as e:
            log.error("%s", e)
            runtime.recalibrate(None, str(e))
    finally:
        readers.start()


def _measure_colour(device: Device, readers: _Readers) -> None:
    """The tap-then-hold gesture: readers stopped, the colour captured and measured,
    the runtime told (on a refusal it keeps the measurement it has)."""
    runtime = device.runtime
    if device.measure_colour is None:
        runtime.remeasured(None, "no camera on this device")
        return
    log.info("colour measurement asked for: stopping the depth camera and IMU readers")
    readers.pause()
    try:
        measured, message = device.measure_colour()
        log.info("surface colour: %s", message)
        runtime.remeasured(measured, message)
    finally:
        readers.start()


def run_loop(device: Device, stop: threading.Event | None = None, retry_s: float = 1.0) -> None:
    """Boot, start a thread per source and one for the link, and feed the runtime on
    this thread until ``stop`` is set (or an interrupt); the recording is closed last."""
    stop = stop or threading.Event()
    runtime, server, tap = device.runtime, device.server, device.tap
    inputs: queue.Queue[Input] = queue.Queue(maxsize=256)
    readers = _Readers(device, inputs, retry_s)
    link = None
    if device.port is not None:
        port = tap.port(device.port) if tap is not None else device.port
        link = threading.Thread(target=serve, args=(port, server, stop), daemon=True, name="link")
    runtime.boot()
    server.restore_active()
    if tap is not None:
        tap.start()
    readers.start()
    if link is not None:
        link.start()
    try:
        while not stop.is_set():
            try:
                item = inputs.get(timeout=0.02)
            except queue.Empty:
                runtime.tick()
            else:
                runtime.tick()
                if tap is not None and isinstance(item, RECORDED):
                    tap.add(item)
                feed(runtime, item)
            if runtime.calibration_wanted:
                _calibrate(device, readers)
            if runtime.colour_wanted:
                _measure_colour(device, readers)
    finally:
        stop.set()
        readers.pause(timeout_s=2.0)  # the readers close their devices
        if tap is not None:
            if link is not None:
                link.join(timeout=1.0)  # its last reply goes into the recording
            n = tap.close()
            log.info("recorded %d records to %s", n, tap.writer.path)


def board_settings(board: Board, settings: AppSettings) -> AppSettings:
    """``settings`` with the board's display: refresh rate, stabilisation margin and
    the brightness gain (made at the display maps' scale when the board turns it on,
    unless ``settings`` already has photometry settings of its own)."""
    d = settings.display
    stabiliser = replace(d.stabiliser, margin=board.display.stabilise_margin)
    display = replace(d, refresh_hz=board.display.refresh_hz, stabiliser=stabiliser)
    photometry = settings.photometry
    if board.display.compensate and photometry is None:
        photometry = PhotometrySettings(scale=settings.map_scale)
    return replace(settings, display=display, photometry=photometry)


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
    settings = board_settings(board, settings or AppSettings())
    display = FramebufferDisplay(
        board.display.device, clock=clock, refresh_hz=board.display.refresh_hz
    )
    runtime = Runtime(calibration, display, clock, [builtin_item()], settings, state_dir=state_dir)
    if settings.photometry is not None:  # the surface's colour, when calibrate measured it
        from adaproj_edge.procam.photometric import load_beside

        runtime.warps.measured = load_beside(board.calibration_path)
    imu_held, depth_held, button_held = _Held(), _Held(), _Held()
    runtime.imu_direct = True  # the IMU's reader feeds the display loop itself

    def open_imu() -> Reader:
        bus = open_i2c(board.imu.bus)
        imu = imu_held.keep(
            Lsm6dsox(bus, clock, board.imu.address, board.imu.config, f"/dev/i2c-{board.imu.bus}")
        )
        imu.start()

        def read() -> ImuSample | None:
            s = imu.read()
            if s is None:  # the FIFO is empty: about a sample's time until the next
                clock.sleep_until(clock.now_ns() + int(1e9 / board.imu.config.rate_hz))
            else:
                runtime.screen.on_imu(s)
            return s

        return read

    def open_depth() -> Reader:
        return depth_held.keep(OakDepthCamera(board.depth, clock)).read

    def open_button() -> Reader:
        button = button_held.keep(EvdevButton(board.button_device, board.key_code, clock))
        return lambda: button.read(0.1)

    def calibrate() -> tuple[Calibration | None, str]:
        from adaproj_edge.app.calibration_run import calibrate_device

        return calibrate_device(board, display, clock, runtime.calibration)

    def measure_colour() -> tuple[Measured | None, str]:
        from adaproj_edge.app.calibration_run import measure_colour_device
        from adaproj_edge.procam.photometric import photometric_path

        out = photometric_path(board.calibration_path)
        return measure_colour_device(board, display, clock, runtime.calibration, out)

    sources = [
        _Source("imu", open_imu, imu_held.close),
        _Source("depth", open_depth, depth_held.close),
        _Source("button", open_button, button_held.close),
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
        device = Device(runtime, server, port, sources, clock, tap, calibrate, True, measure_colour)
        run_loop(device, retry_s=retry_s)
    finally:
        display.close()
