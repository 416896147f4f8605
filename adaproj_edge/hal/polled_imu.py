"""An IMU read on a thread of its own, for a caller busy elsewhere between reads.

The calibration procedure waits on the camera for hundreds of milliseconds at a time;
without a reader of its own the IMU's samples in between would be lost (the chip keeps
only a bounded FIFO, and the register path only its newest sample).
"""

from __future__ import annotations

import queue
import threading

from adaproj_edge.errors import DeviceError
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.imu import Imu, ImuSample


class PolledImu:
    """``imu`` read on a thread; :meth:`read` hands out every sample in order.

    Parameters
    ----------
    imu : Imu
        The device (closed by :meth:`close`).
    rate_hz : float
        Its output data rate: an empty read waits half a period.
    clock : Clock
    """

    def __init__(self, imu: Imu, rate_hz: float, clock: Clock) -> None:
        self._imu, self._clock = imu, clock
        self._period_ns = int(0.5e9 / rate_hz)
        self._queue: queue.Queue[ImuSample] = queue.Queue(maxsize=100_000)
        self._stop = threading.Event()
        self._error: str | None = None
        self._thread = threading.Thread(target=self._run, name="imu", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                s = self._imu.read()
                if s is None:
                    self._clock.sleep_until(self._clock.now_ns() + self._period_ns)
                else:
                    self._queue.put(s)
        except Exception as e:  # handed to the reader, who reports it
            self._error = str(e) or type(e).__name__

    def read(self) -> ImuSample | None:
        """The next sample read, or None when none is waiting.

        Raises
        ------
        DeviceError
            The IMU failed on the reading thread (after the samples read before it).
        """
        try:
            return self._queue.get_nowait()
        except queue.Empty:
            if self._error is not None:
                raise DeviceError(f"the IMU failed: {self._error}") from None
            return None

    def close(self) -> None:
        """Stop the thread and close the IMU."""
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._imu.close()
