"""Motion from the IMU: moving / settled with hysteresis, and the device's orientation.

The device counts as *moving* as soon as a short window of IMU samples is not still
(:func:`~adaproj_edge.geometry.depth.is_still`: gyro rate and accelerometer jitter),
and as *settled* again only after ``settle_s`` of stillness, so a hand that is nearly
still does not toggle between the two. The orientation is the integrated gyro (bias
estimated while still), rotated into the projector frame P; it only serves as part of
the pose cache key, so slow drift is harmless.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from adaproj_edge.geometry.depth import is_still
from adaproj_edge.geometry.projector import FloatArray
from adaproj_edge.hal.imu import ImuSample


@dataclass(frozen=True)
class MotionSettings:
    """Hysteresis of the motion detector (seconds)."""

    window_s: float = 0.2
    settle_s: float = 0.3


def _rotation(r: FloatArray) -> FloatArray:
    """Rotation matrix of the rotation vector ``r`` (3,)."""
    theta = float(np.linalg.norm(r))
    if theta < 1e-12:
        return np.eye(3)
    k = r / theta
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(theta) * kx + (1 - np.cos(theta)) * (kx @ kx)  # type: ignore[no-any-return]


def rotation_vector(R: FloatArray) -> FloatArray:
    """Rotation vector (3,) of a rotation matrix (3, 3)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(c))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-9:
        return w / 2.0
    return w * (theta / (2.0 * np.sin(theta)))  # type: ignore[no-any-return]


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
            self.orientation = self.orientation @ _rotation(w_p * dt)
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
