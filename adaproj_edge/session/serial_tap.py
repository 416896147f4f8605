"""Serial traffic in sessions: a port wrapper that records, and a port that replays.

:class:`RecordingPort` wraps any :class:`~adaproj_edge.hal.serial.SerialPort` and hands
every chunk read (``rx``, from the host) and written (``tx``, to the host) to a sink,
such as :meth:`adaproj_edge.session.recorder.Recorder.serial`. :class:`ReplayPort`
gives the recorded ``rx`` chunks back through ``read`` on a virtual clock and keeps
what the code under replay writes, so it can be compared with the recorded ``tx``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.recorded import ReplayStream
from adaproj_edge.hal.serial import SerialPort
from adaproj_edge.session.records import SerialTraffic

Sink = Callable[[str, bytes], None]


class RecordingPort:
    """A serial port whose traffic is also sent to ``sink(direction, data)``."""

    def __init__(self, port: SerialPort, sink: Sink) -> None:
        self.port = port
        self.sink = sink

    def read(self, size: int, timeout: float) -> bytes:
        """Read from the wrapped port; what came is sent to the sink as ``rx``."""
        data = self.port.read(size, timeout)
        if data:
            self.sink("rx", data)
        return data

    def write(self, data: bytes) -> None:
        """Write to the wrapped port, then send ``data`` to the sink as ``tx``."""
        self.port.write(data)
        self.sink("tx", bytes(data))

    def close(self) -> None:
        """Close the wrapped port."""
        self.port.close()


class ReplayPort:
    """Recorded ``rx`` chunks through ``read``; ``write`` keeps what is written.

    A recorded chunk larger than ``size`` is handed out over several reads; at the end
    of the recording ``read`` returns ``b""`` (a timeout).
    """

    def __init__(self, traffic: Iterable[SerialTraffic], clock: VirtualClock) -> None:
        rx = (t for t in traffic if t.direction == "rx")
        self._stream = ReplayStream(rx, clock)
        self._pending = b""
        self.written: list[bytes] = []

    def read(self, size: int, timeout: float) -> bytes:
        """At most ``size`` bytes of the next recorded ``rx`` chunk (``timeout`` is ignored);
        ``b""`` at the end of the recording."""
        if not self._pending:
            rec = self._stream.next()
            if rec is None:
                return b""
            self._pending = rec.data
        out, self._pending = self._pending[:size], self._pending[size:]
        return out

    def write(self, data: bytes) -> None:
        """Keep ``data`` in :attr:`written`."""
        self.written.append(bytes(data))

    def close(self) -> None:
        """Nothing to release."""
        pass
