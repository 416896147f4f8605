"""Motion from the IMU: moving / settled with hysteresis, and the device's orientation.

The device counts as *moving* as soon as a short window of IMU samples is not still
(:func:`is_still`: gyro rate and accelerometer jitter),
and as *settled* again only after ``settle_s`` of stillness, so a hand that is nearly
still does not toggle between the two. The orientation is the integrated gyro (bias
estimated while still), rotated into the projector frame P; it only serves as part of
the pose cache key, so slow drift is harmless.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rotations import rotation_matrix, rotation_vector
from adaproj_edge.hal.imu import ImuSample


def is_still(
    gyro: FloatArray, accel: FloatArray, max_rate: float = 0.03, max_accel_std: float = 0.3
) -> bool:
    """Whether IMU samples (N, 3) gyro rad/s and (N, 3) accel m/s^2 show a still device."""
    g = np.asarray(gyro, dtype=np.float64).reshape(-1, 3)
    a = np.asarray(accel, dtype=np.float64).reshape(-1, 3)
    if len(g) < 2:
        return False
    rate = float(np.linalg.norm(np.median(g, axis=0)))
    jitter = float(np.max(np.std(a, axis=0)))
    return rate <= max_rate and jitter <= max_accel_std


@dataclass(frozen=True)
class MotionSettings:
    """Hysteresis of the motion detector (seconds)."""

    window_s: float = 0.2
    settle_s: float = 0.3


class MotionTracker:
    """Feeds on IMU samples; says whether the device moves and where it points.

    Parameters
    ----------
    R_P_I : (3, 3) rotation from the IMU frame to the projector frame.
    settings : MotionSettings
    """

    def __init__(self, R_P_I: FloatArray, settings: MotionSettings | None = None) -> None:
        self.R_P_I = np.asarray(R_P_I, dtype=np.float64)
        self.settings = settings or MotionSettings()
        self._window: deque[ImuSample] = deque()
        self._last_ns: int | None = None
        self._still_since: int | None = None
        self.moving = False
        self.orientation = np.eye(3)  # R_W_P, W = P at the first sample
        self._bias = np.zeros(3)
        self._bias_n = 0

    def update(self, sample: ImuSample) -> bool | None:
        """Take one sample; returns True when motion starts, False when the device has
        settled, None when nothing changed."""
        t = sample.sensor_ns
        gyro = np.asarray(sample.gyro, dtype=np.float64)
        if self._last_ns is not None and t > self._last_ns:
            dt = min((t - self._last_ns) * 1e-9, 0.1)
            w_p = self.R_P_I @ (gyro - self._bias)
            self.orientation = self.orientation @ rotation_matrix(w_p * dt)
        self._last_ns = t
        self._window.append(sample)
        horizon = t - int(self.settings.window_s * 1e9)
        while self._window and self._window[0].sensor_ns < horizon:
            self._window.popleft()
        if len(self._window) < 8:
            return None  # too few samples to judge (start, or after a fault)
        still = is_still(
            np.array([s.gyro for s in self._window]),
            np.array([s.accel for s in self._window]),
        )
        if still:
            # the bias is learnt from quiet samples only (a turn starting inside a
            # still window must not become bias)
            if self._bias_n < 2000 and not self.moving and np.linalg.norm(gyro) < 0.03:
                self._bias_n += 1
                self._bias += (gyro - self._bias) / self._bias_n
            if self._still_since is None:
                self._still_since = t
        else:
            self._still_since = None
        if not still and not self.moving:
            self.moving = True
            return True
        if (
            self.moving
            and self._still_since is not None
            and t - self._still_since >= int(self.settings.settle_s * 1e9)
        ):
            self.moving = False
            return False
        return None

    def reset_window(self) -> None:
        """Forget recent samples (after an IMU fault): the next ones decide afresh."""
        self._window.clear()
        self._last_ns = None
        self._still_since = None

    def orientation_vector(self) -> FloatArray:
        """The orientation R_W_P as a rotation vector (3,) in radians."""
        return rotation_vector(self.orientation)
