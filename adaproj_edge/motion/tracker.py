"""Motion from the IMU: moving / settled with hysteresis, and the device's orientation.

The device counts as *moving* as soon as it turns on purpose (the gyro rate, its bias
removed, low-passed so that the hand's 8-12 Hz tremor does not count:
:class:`~adaproj_edge.motion.rates.LowPass2`, over ``max_rate``) or shakes (the
jitter over a short window of the accelerometer low-passed with ``accel_lowpass_s``:
the tremor swings a hand-held device on the wrist's lever by several m/s^2 at 8-12 Hz,
which is not a move), and as *settled* again only after
``settle_s`` of stillness, so a hand that is nearly still does not toggle between the
two. The orientation is the integrated gyro (bias learnt while still,
:class:`~adaproj_edge.motion.rates.GyroBias`), rotated into the projector frame P; it
only serves as part of the pose cache key, so slow drift is harmless.

:func:`is_still` is the windowed test of recorded samples (median rate, accelerometer
jitter) that :mod:`adaproj_edge.session.track` uses offline.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rotations import rotation_matrix, rotation_vector
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.motion.rates import GyroBias, LowPass2


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
    """The motion detector: its window and hysteresis (seconds), the deliberate rate
    (rad/s, after a two-stage low-pass of ``lowpass_s``) and accelerometer jitter
    (m/s^2, standard deviation over the window of the accelerometer after a two-stage
    low-pass of ``accel_lowpass_s``) under which the device is still."""

    window_s: float = 0.2
    settle_s: float = 0.3
    max_rate: float = 0.03
    max_accel_std: float = 0.3
    lowpass_s: float = 0.08
    accel_lowpass_s: float = 0.15


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
        self._window: deque[tuple[int, FloatArray]] = deque()  # low-passed accel
        self._last_ns: int | None = None
        self._still_since: int | None = None
        self.moving = False
        self.orientation = np.eye(3)  # R_W_P, W = P at the first sample
        self._rate = LowPass2(self.settings.lowpass_s)
        self._accel = LowPass2(self.settings.accel_lowpass_s)
        self._accel_started = False
        self.bias = GyroBias(lowpass_s=self.settings.lowpass_s, smooth=True)

    def update(self, sample: ImuSample) -> bool | None:
        """Take one sample; returns True when motion starts, False when the device has
        settled, None when nothing changed."""
        t = sample.sensor_ns
        gyro = np.asarray(sample.gyro, dtype=np.float64)
        accel = np.asarray(sample.accel, dtype=np.float64)
        if not self._accel_started:  # the low-pass starts at the first sample, not 0
            self._accel.update(accel, self._accel.tau_s)
            self._accel.update(accel, self._accel.tau_s)
            self._accel_started = True
        if self._last_ns is not None and t > self._last_ns:
            dt = min((t - self._last_ns) * 1e-9, 0.1)
            w = gyro - self.bias.value
            self.orientation = self.orientation @ rotation_matrix(self.R_P_I @ w * dt)
            self._rate.update(w, dt)
            self._accel.update(accel, dt)
            self.bias.update(gyro, dt)
        self._last_ns = t
        self._window.append((t, self._accel.value.copy()))
        horizon = t - int(self.settings.window_s * 1e9)
        while self._window and self._window[0][0] < horizon:
            self._window.popleft()
        if len(self._window) < 8:
            return None  # too few samples to judge (start, or after a fault)
        s = self.settings
        jitter = float(np.max(np.std(np.array([x[1] for x in self._window]), axis=0)))
        still = self.deliberate_rate <= s.max_rate and jitter <= s.max_accel_std
        if still:
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
        self._rate.reset()
        self._accel.reset()
        self._accel_started = False
        self.bias.reset_stillness()

    @property
    def deliberate_rate(self) -> float:
        """The low-passed turning rate (rad/s), bias and tremor taken out."""
        return float(np.linalg.norm(self._rate.value))

    def orientation_vector(self) -> FloatArray:
        """The orientation R_W_P as a rotation vector (3,) in radians."""
        return rotation_vector(self.orientation)
