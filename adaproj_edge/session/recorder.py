"""Recording a session on the device: one thread per sensor, one writer.

Each source is a callable returning the next record (or None when it has none yet);
a thread per source pushes records into one queue, and the caller's thread writes
them in arrival order, flushing (chunk + fsync) every ``flush_every_s`` so a power
loss costs at most that much. Serial traffic arrives through :meth:`Recorder.serial`,
which the link can call from any thread.

:class:`SessionTap` records alongside the running device (``adaproj run --record``):
the inputs the runtime is handed and the link's traffic (its port wrapped in a
:class:`~adaproj_edge.session.serial_tap.RecordingPort`), written on a thread of its
own through the same :class:`Recorder` and :class:`SessionWriter`.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable

from adaproj_edge.errors import AdaprojError
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.serial import SerialPort
from adaproj_edge.session.codec import Record
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.serial_tap import RecordingPort
from adaproj_edge.session.writer import SessionWriter

log = logging.getLogger(__name__)

Source = Callable[[], Record | None]


class Recorder:
    """Writes records from several sources into one session."""

    def __init__(self, writer: SessionWriter, clock: Clock, flush_every_s: float = 1.0) -> None:
        self.writer = writer
        self.clock = clock
        self.flush_every_ns = int(flush_every_s * 1e9)
        self._queue: queue.Queue[Record] = queue.Queue()
        self._stop = threading.Event()
        self._errors: list[BaseException] = []

    def add(self, rec: Record) -> None:
        """Queue one record (thread-safe)."""
        self._queue.put(rec)

    def serial(self, direction: str, data: bytes) -> None:
        """Record bytes seen on the serial link (``"rx"`` or ``"tx"``)."""
        self.add(SerialTraffic(self.clock.now_ns(), direction, bytes(data)))

    def stop(self) -> None:
        """Make :meth:`run` finish (thread-safe)."""
        self._stop.set()

    def _pump(self, source: Source) -> None:
        try:
            while not self._stop.is_set():
                rec = source()
                if rec is not None:
                    self.add(rec)
        except BaseException as e:  # handed to the writing thread, which re-raises it
            self._errors.append(e)
            self._stop.set()

    def run(self, sources: dict[str, Source], seconds: float | None = None) -> int:
        """Record until ``seconds`` have passed on the clock, :meth:`stop` or an error.

        Returns the number of records written; a device error is re-raised after
        everything received so far is written and the file is closed.
        """
        threads = [
            threading.Thread(target=self._pump, args=(src,), name=f"record-{name}", daemon=True)
            for name, src in sources.items()
        ]
        start = self.clock.now_ns()
        end = None if seconds is None else start + int(seconds * 1e9)
        last_flush = start
        for t in threads:
            t.start()
        try:
            while not self._stop.is_set():
                now = self.clock.now_ns()
                if end is not None and now >= end:
                    break
                try:
                    self.writer.write(self._queue.get(timeout=0.05))
                except queue.Empty:
                    pass
                if now - last_flush >= self.flush_every_ns:
                    self.writer.flush()
                    last_flush = now
        finally:
            self._stop.set()
            for t in threads:
                t.join(timeout=2.0)
            while not self._queue.empty():
                self.writer.write(self._queue.get_nowait())
            self.writer.close()
        if self._errors:
            e = self._errors[0]
            if isinstance(e, AdaprojError):
                raise e
            raise AdaprojError(f"recording stopped: {e!r}") from e
        return self.writer.count


class SessionTap:
    """A session recorded while the device runs: hand it every input record
    (:meth:`add`) and let it wrap the serial port (:meth:`port`); a thread writes
    them, flushing every ``flush_every_s``. A write error (a full disk) ends the
    recording with a logged reason, never the device.
    """

    def __init__(self, writer: SessionWriter, clock: Clock, flush_every_s: float = 1.0) -> None:
        self.writer = writer
        self.recorder = Recorder(writer, clock, flush_every_s)
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name="record", daemon=True)

    def _run(self) -> None:
        try:
            self.recorder.run({})
        except (AdaprojError, OSError) as e:
            self.error = f"recording to {self.writer.path} stopped: {e}"
            log.error("%s", self.error)

    def start(self) -> None:
        """Start the writer thread."""
        self._thread.start()

    def add(self, rec: Record) -> None:
        """Record one input (thread-safe)."""
        if self.error is None:
            self.recorder.add(rec)

    def port(self, port: SerialPort) -> RecordingPort:
        """``port`` with its traffic recorded (``/serial/rx``, ``/serial/tx``)."""
        return RecordingPort(port, self._serial)

    def _serial(self, direction: str, data: bytes) -> None:
        if self.error is None:
            self.recorder.serial(direction, data)

    def close(self, timeout_s: float = 10.0) -> int:
        """Write what is queued, close the file; the number of records written."""
        self.recorder.stop()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        if not self._thread.is_alive():
            self.writer.close()
        return self.writer.count
