"""Which way is up, from the accelerometer: the warp's "up" in the projector frame P.

At rest the accelerometer measures the specific force, gravity's reaction: a vector
pointing up (about (0, -9.81, 0) in a level device whose y axis points down). The
estimate is a complementary filter in frame P: each gyro sample turns it with the
device (a direction fixed in the world, seen from a turning body), and while the
device is nearly still (the measured magnitude within ``max_deviation`` of gravity,
the rate under ``max_rate``) it is pulled towards the measured direction with time
constant ``tau_s``, which averages the hand's tremor and the sensor noise away.

The accelerometer's zero-g offset tilts the result directly (10 mg is 0.6 degrees):
a unit's offset must be calibrated for the content to stand upright within a degree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rotations import rotation_matrix

STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class GravitySettings:
    """Tuning of the gravity filter (seconds, m/s^2, rad/s).

    tau_s : float
        Time constant of the pull towards the measured direction.
    max_deviation : float
        Samples whose magnitude is further than this from gravity are not used.
    max_rate : float
        Samples taken while the device turns faster than this are not used.
    settle_s : float
        Seconds of usable samples before the estimate is trusted.
    """

    tau_s: float = 1.0
    max_deviation: float = 0.5
    max_rate: float = 0.5
    settle_s: float = 0.5


class GravityFilter:
    """Up (unit vector in frame P) from accelerometer and gyro samples in frame P.

    Parameters
    ----------
    settings : GravitySettings
    """

    def __init__(self, settings: GravitySettings | None = None) -> None:
        self.settings = settings or GravitySettings()
        self._up: FloatArray | None = None
        self._last_ns: int | None = None
        self._used_s = 0.0

    def update(self, t_ns: int, accel: FloatArray, rate: FloatArray, still: bool = True) -> None:
        """One sample: specific force (3,) m/s^2 and angular rate (3,) rad/s, frame P;
        ``still``: whether the device is held still (only then is gravity measured)."""
        s = self.settings
        a = np.asarray(accel, dtype=np.float64)
        w = np.asarray(rate, dtype=np.float64)
        dt = 0.0 if self._last_ns is None else max(0.0, (t_ns - self._last_ns) * 1e-9)
        self._last_ns = t_ns
        dt = min(dt, 0.1)
        if self._up is not None and dt > 0:
            # a world direction seen from a body turning by w: rotates by -w dt
            self._up = rotation_matrix(w * dt).T @ self._up
        norm = float(np.linalg.norm(a))
        usable = abs(norm - STANDARD_GRAVITY) <= s.max_deviation and np.linalg.norm(w) <= s.max_rate
        if not usable or norm == 0.0:
            return
        meas = a / norm
        if self._up is None:
            self._up = meas  # a first guess, moving or not
            return
        if not still:
            return
        self._used_s += dt
        k = min(1.0, dt / min(max(self._used_s, dt), s.tau_s))
        up = self._up + k * (meas - self._up)
        self._up = up / np.linalg.norm(up)

    def reset(self) -> None:
        """Forget the estimate (after an IMU fault)."""
        self._up = None
        self._last_ns = None
        self._used_s = 0.0

    @property
    def ready(self) -> bool:
        """Whether enough still samples have been seen to trust :attr:`up`."""
        return self._up is not None and self._used_s >= self.settings.settle_s

    @property
    def up(self) -> FloatArray | None:
        """Up (3,) as a unit vector in frame P, None before any usable sample."""
        return None if self._up is None else self._up.copy()
