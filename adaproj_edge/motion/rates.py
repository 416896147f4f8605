"""The gyro's slow part: the deliberate turning rate (tremor filtered out) and the
gyro's bias, learnt while the device is held still. Shared by the motion tracker (still
or moving) and the stabiliser (how fast to follow).

:class:`LowPass2` is two first-order low-passes in a row (time constant ``tau_s``
each): 8-12 Hz tremor is cut by about 40 dB per decade above ``1 / (2 pi tau_s)``, a
turn shows within a few ``tau_s``.

:class:`GyroBias` averages the rate (time constant ``tau_s``) over stretches where the
low-passed raw rate, bias included (so that a wrong estimate cannot shut the learning
out), stays under ``still_rate``: a sample counts once the device has stayed still for
``hold_s`` after it, so the first samples of a turn (before the low-pass shows it) are
never learnt. Tremor and sway average out. The estimate is kept within ``max_bias`` per
axis (an LSM6DSOX's zero-rate level is about 1 dps).

:class:`WindowMean` is the mean of a 3-vector over the last ``window_s``: of the
low-passed rate, the rotation it accumulates over the window, divided by it. Held
still, what the low-pass leaves of a strong tremor (0.5 degrees RMS: about 0.04 rad/s,
as much as a slow deliberate turn) still swings to and fro every 40-125 ms and
averages out over 0.2 s; a turn keeps one direction and stays.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from adaproj_edge.arrays import FloatArray


class LowPass2:
    """Two cascaded first-order low-passes of a 3-vector.

    Parameters
    ----------
    tau_s : float
        Time constant of each stage (seconds).
    """

    def __init__(self, tau_s: float) -> None:
        self.tau_s = tau_s
        self._a = np.zeros(3)
        self._b = np.zeros(3)

    def update(self, x: FloatArray, dt: float) -> FloatArray:
        """Take ``x`` (3,) after ``dt`` seconds; the filtered value (3,)."""
        k = min(1.0, dt / self.tau_s)
        self._a += (np.asarray(x, dtype=np.float64) - self._a) * k
        self._b += (self._a - self._b) * k
        return self._b

    @property
    def value(self) -> FloatArray:
        """The filtered value (3,)."""
        return self._b

    def reset(self) -> None:
        """Back to zero."""
        self._a[:] = 0.0
        self._b[:] = 0.0


class GyroBias:
    """The gyro's zero-rate offset (3,) rad/s, learnt while still.

    Parameters
    ----------
    tau_s, still_rate, hold_s, max_bias : float
        Averaging time constant (s), the low-passed raw rate under which (rad/s), held
        for how long (s), the learning runs, and the largest offset per axis (rad/s).
    lowpass_s : float
        Time constant of the low-pass that tells stillness.
    smooth : bool
        Learn from that low-passed rate instead of the raw one (the hand's tremor out
        of the average: at 0.5 degrees RMS it swings the raw rate by about 1 rad/s).

    Attributes
    ----------
    value : (3,) rad/s, the offset learnt; learnt_s : seconds of samples it rests on.
    """

    def __init__(
        self,
        tau_s: float = 20.0,
        still_rate: float = 0.05,
        hold_s: float = 0.3,
        max_bias: float = 0.05,
        lowpass_s: float = 0.08,
        smooth: bool = False,
    ) -> None:
        self.tau_s, self.still_rate, self.hold_s, self.max_bias = (
            tau_s,
            still_rate,
            hold_s,
            max_bias,
        )
        self.raw = LowPass2(lowpass_s)
        self.smooth = smooth
        self.value = np.zeros(3)
        self.learnt_s = 0.0  # seconds of samples learnt from
        self._weight = 0.0
        self._pending: deque[tuple[FloatArray, float]] = deque()
        self._pending_s = 0.0

    def update(self, rate: FloatArray, dt: float) -> None:
        """Take one raw rate sample (3,) rad/s, ``dt`` seconds after the last."""
        w = np.asarray(rate, dtype=np.float64)
        low = self.raw.update(w, dt)
        if float(np.linalg.norm(low)) >= self.still_rate:
            self._pending.clear()
            self._pending_s = 0.0
            return
        self._pending.append((low.copy() if self.smooth else w, dt))
        self._pending_s += dt
        while self._pending and self._pending_s - self._pending[0][1] >= self.hold_s:
            old, odt = self._pending.popleft()
            self._pending_s -= odt
            self.learnt_s += odt
            # the weight grows from 1 s: the first still seconds count, none alone
            self._weight = min(max(self._weight + odt, 1.0), self.tau_s)
            b = self.value + (old - self.value) * (odt / self._weight)
            self.value = np.clip(b, -self.max_bias, self.max_bias)

    def reset_stillness(self) -> None:
        """Forget the recent samples (after a gap in them)."""
        self.raw.reset()
        self._pending.clear()
        self._pending_s = 0.0


class WindowMean:
    """The mean of a 3-vector over the last ``window_s`` seconds (the sum of its samples
    times their ``dt`` over the window, divided by ``window_s``: until the window is
    full it reads low).

    Parameters
    ----------
    window_s : float
        The window (seconds).
    """

    def __init__(self, window_s: float) -> None:
        self.window_s = window_s
        self._items: deque[tuple[FloatArray, float]] = deque()
        self._sum = np.zeros(3)
        self._span_s = 0.0
        self._count = 0

    def update(self, x: FloatArray, dt: float) -> FloatArray:
        """Take ``x`` (3,), held for the ``dt`` seconds up to now; the mean (3,)."""
        step = np.asarray(x, dtype=np.float64) * dt
        self._items.append((step, dt))
        self._sum += step
        self._span_s += dt
        while self._items and self._span_s - self._items[0][1] >= self.window_s:
            old, odt = self._items.popleft()
            self._sum -= old
            self._span_s -= odt
        self._count += 1
        if self._count >= 4096:  # the running sum re-added now and then (rounding)
            self._sum = np.sum([v for v, _ in self._items], axis=0)
            self._count = 0
        return self.value

    @property
    def value(self) -> FloatArray:
        """The mean (3,)."""
        out: FloatArray = self._sum / self.window_s
        return out

    def reset(self) -> None:
        """Forget the window."""
        self._items.clear()
        self._sum = np.zeros(3)
        self._span_s = 0.0
