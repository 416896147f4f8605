"""The device's orientation from its gyro, integrated sample by sample and predicted a
few milliseconds ahead (to the moment a frame is lit).

The gyro reports the angular rate in the IMU frame; :class:`GyroTrack` takes it in the
projector frame P (the caller rotates by ``R_P_I``), removes a bias, integrates it
(trapezoidal rule, ``R_k = R_{k-1} exp((w_{k-1} + w_k) dt / 2)``) and keeps the last
rates for prediction.

Prediction (:meth:`GyroTrack.predict`)
--------------------------------------
A hand's tremor is a narrow-band oscillation (8-12 Hz): extrapolating the rate as a
constant (or a low-order polynomial) lags it by a large part of its amplitude 10-20 ms
ahead. Instead each axis's rate, less its straight-line trend over the last
``ar_window_s`` (a deliberate turn, carried on as it is), is fitted by an
autoregressive model of order ``ar_order`` (least squares: the linear predictor of a
stationary signal from its own past, which adapts to whatever spectrum the hand has)
and run forward sample by sample to the wanted time; the predicted rates are
integrated onto the newest orientation. A fit that grows (a root of its polynomial
beyond ``MAX_ROOT``) or whose prediction leaves the range seen in the window falls
back to a quadratic fitted to the last ``fallback_window_s`` of rates (a Taylor
extrapolation). ``method="constant"`` holds the newest rate, ``"none"`` the newest
orientation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from adaproj_edge.arrays import FloatArray

PredictMethod = Literal["ar", "constant", "none"]
MAX_ROOT = 1.05  # a fit of a narrow-band oscillation has roots near the unit circle


@dataclass(frozen=True)
class PredictionSettings:
    """How the orientation is predicted ahead (seconds, samples).

    method : "ar" (autoregressive, default), "constant" (newest rate) or "none"
    ar_order : int
        Past samples each predicted rate depends on.
    ar_window_s : float
        Samples the model is fitted on.
    max_gap_s : float
        A longer gap between samples (an IMU fault) starts the history afresh.
    fallback_window_s : float
        Samples the fallback's quadratic is fitted on.
    """

    method: PredictMethod = "ar"
    ar_order: int = 4
    ar_window_s: float = 0.5
    max_gap_s: float = 0.05
    fallback_window_s: float = 0.015


class GyroTrack:
    """Integrated orientation ``R_W_P`` (W: the frame at the first sample) and the recent
    rates, for prediction.

    Parameters
    ----------
    settings : PredictionSettings
    capacity : int
        Rates kept (at least the fitting window's worth).
    """

    def __init__(self, settings: PredictionSettings | None = None, capacity: int = 1024) -> None:
        self.settings = settings or PredictionSettings()
        self.capacity = capacity
        self._t = np.zeros(capacity, np.int64)
        self._w = np.zeros((capacity, 3))
        self._n = 0  # samples held (<= capacity), newest at index (_n - 1) % capacity
        self._head = 0  # index of the next write
        self.orientation = np.eye(3)
        self.bias = np.zeros(3)
        self.samples = 0  # accepted since the last reset

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the rates (after a gap); the orientation is kept."""
        self._n = 0
        self._head = 0

    @property
    def last_ns(self) -> int | None:
        """Time of the newest sample (ns), None before any."""
        if self._n == 0:
            return None
        return int(self._t[(self._head - 1) % self.capacity])

    def rates(self, n: int | None = None) -> tuple[FloatArray, FloatArray]:
        """The newest ``n`` (default: all kept) sample times (s, relative to the newest)
        and raw rates (n, 3), oldest first."""
        k = self._n if n is None else min(n, self._n)
        idx = (self._head - k + np.arange(k)) % self.capacity
        t = (self._t[idx] - self._t[(self._head - 1) % self.capacity]) * 1e-9
        return t.astype(np.float64), self._w[idx].copy()

    # ------------------------------------------------------------------ input
    def add(self, t_ns: int, rate: FloatArray) -> bool:
        """Take one rate sample (3,) rad/s in frame P at ``t_ns``; returns False when it
        was refused (not after the newest sample)."""
        w = np.asarray(rate, dtype=np.float64).reshape(3)
        last = self.last_ns
        if last is not None:
            if t_ns <= last:
                return False
            dt = (t_ns - last) * 1e-9
            if dt > self.settings.max_gap_s:
                self.reset()
            else:
                prev = self._w[(self._head - 1) % self.capacity]
                step = 0.5 * (prev + w) - self.bias
                self.orientation = self.orientation @ small_rotation(step * dt)
        self._t[self._head] = t_ns
        self._w[self._head] = w
        self._head = (self._head + 1) % self.capacity
        self._n = min(self._n + 1, self.capacity)
        self.samples += 1
        return True

    # ------------------------------------------------------------------ output
    def predict(self, t_ns: int) -> FloatArray:
        """The orientation (3, 3) predicted at ``t_ns`` (the newest one for a time at or
        before the newest sample)."""
        last = self.last_ns
        if last is None or t_ns <= last or self.settings.method == "none":
            return self.orientation.copy()
        h = (t_ns - last) * 1e-9
        return self.orientation @ small_rotation(self._integral(h))

    def _integral(self, h: float) -> FloatArray:
        """The predicted rotation (rotation vector, 3) over the next ``h`` seconds."""
        s = self.settings
        t, w = self.rates()
        newest: FloatArray = w[-1] - self.bias
        if s.method == "constant" or len(t) < 3:
            return newest * h
        dt = float(np.median(np.diff(t)))
        n = round(s.ar_window_s / dt) if dt > 0 else 0
        p = s.ar_order
        if n < 4 * p or len(t) < n:
            return newest * h
        got = _ar_forward(w[-n:], p, dt, h)
        if got is None:
            got = _taylor_forward(w[-max(3, round(s.fallback_window_s / dt)) :], dt, h)
        return got - self.bias * h


def _ar_forward(w: FloatArray, p: int, dt: float, h: float) -> FloatArray | None:
    """The integral over the next ``h`` seconds of the rates (n, 3) sampled every ``dt``:
    each axis's straight-line trend over the window carried on, plus what is left
    (the oscillation) continued by an AR(``p``) least-squares fit; None when a fit is
    unusable (singular, unstable, or its prediction leaves the range of the window)."""
    n = len(w)
    x = (np.arange(n) - (n - 1)) * dt  # 0 at the newest sample
    A = np.stack([np.ones(n), x], axis=1)
    trend, *_ = np.linalg.lstsq(A, w, rcond=None)  # (2, 3)
    y = w - A @ trend
    steps = int(np.ceil(h / dt - 1e-9))
    out = np.empty(3)
    for a in range(3):
        ya = y[:, a]
        X = np.stack([ya[p - 1 - i : n - 1 - i] for i in range(p)], axis=1)
        coef, _, rank, _ = np.linalg.lstsq(X, ya[p:], rcond=None)
        if rank < p or np.max(np.abs(np.roots(np.r_[1.0, -coef]))) > MAX_ROOT:
            return None
        hist = list(ya[-p:][::-1])
        r = [float(ya[-1])]
        for _ in range(steps):
            v = float(np.dot(coef, hist))
            r.append(v)
            hist = [v, *hist[:-1]]
        bound = 1.5 * float(np.max(np.abs(ya)))
        if max(abs(v) for v in r) > bound:
            return None
        # trapezoids over whole steps, the last one cut at h
        total = 0.0
        for j in range(steps):
            width = min(dt, h - j * dt)
            if width <= 0:
                break
            end = r[j] + (r[j + 1] - r[j]) * (width / dt)
            total += 0.5 * (r[j] + end) * width
        # the trend: c0 + c1 t integrated over [0, h]
        out[a] = total + trend[0, a] * h + 0.5 * trend[1, a] * h * h
    return out


def _taylor_forward(w: FloatArray, dt: float, h: float) -> FloatArray:
    """The integral over the next ``h`` seconds of the rates (n, 3) sampled every
    ``dt``, each axis continued by the quadratic fitted to them (a straight line for
    fewer than 4 samples)."""
    n = len(w)
    x = (np.arange(n) - (n - 1)) * dt
    deg = 2 if n >= 4 else 1
    c = np.polynomial.polynomial.polyfit(x, w, deg)  # (deg + 1, 3), low order first
    powers = np.array([h ** (k + 1) / (k + 1) for k in range(deg + 1)])
    out: FloatArray = powers @ c
    return out


def small_rotation(r: FloatArray) -> FloatArray:
    """Rotation matrix (3, 3) of one rotation vector ``r`` (3,) (Rodrigues' formula in
    scalar arithmetic: the display loop calls it for every gyro sample, where the
    vectorised :func:`~adaproj_edge.geometry.rotations.rodrigues` costs ten times more)."""
    x, y, z = float(r[0]), float(r[1]), float(r[2])
    t2 = x * x + y * y + z * z
    if t2 < 1e-24:
        a, b = 1.0, 0.5
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    return np.array(
        [
            [1.0 - b * (y * y + z * z), -a * z + b * x * y, a * y + b * x * z],
            [a * z + b * x * y, 1.0 - b * (x * x + z * z), -a * x + b * y * z],
            [-a * y + b * x * z, a * x + b * y * z, 1.0 - b * (x * x + y * y)],
        ]
    )
