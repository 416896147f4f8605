"""Recording a session on the device: one thread per sensor, one writer.

Each source is a callable returning the next record (or None when it has none yet);
a thread per source pushes records into one queue, and the caller's thread writes
them in arrival order, flushing (chunk + fsync) every ``flush_every_s`` so a power
loss costs at most that much. Serial traffic arrives through :meth:`Recorder.serial`,
which the link can call from any thread.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable

from adaproj_edge.errors import AdaprojError
from adaproj_edge.hal.clock import Clock
from adaproj_edge.session.codec import Record
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.writer import SessionWriter

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
