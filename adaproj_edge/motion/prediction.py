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
integrated onto the newest orientation. The three axes are fitted as one batch and the
coefficients are kept for ``ar_refit_s`` (the trend and the run forward are redone at
every prediction): the display thread predicts at every refresh, and refitting each
time was most of its filter's cost. An axis with no oscillation left (a pure turn, an
idle axis) is carried by its trend alone. A fit that grows (a root of its polynomial
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
FLAT_RATE = 1e-9  # rad/s: residuals below this are rounding, nothing to fit
RATE_PROBE = 33  # newest samples whose median interval is the sampling interval


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
    ar_refit_s : float
        The model's coefficients are fitted again once the newest sample is this much
        newer than the last fit (the hand's tremor spectrum changes over seconds); the
        trend and the run forward are done at every prediction.
    """

    method: PredictMethod = "ar"
    ar_order: int = 4
    ar_window_s: float = 0.5
    ar_refit_s: float = 0.05
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
        self._coef: FloatArray | None = None  # the AR fit (3, p), None: none usable
        self._fit_key: tuple[int, int] | None = None  # (newest sample ns, window) of it

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the rates (after a gap); the orientation is kept."""
        self._n = 0
        self._head = 0
        self._fit_key = None

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
        t, w = self.rates(RATE_PROBE)  # enough to know the sampling interval
        newest: FloatArray = w[-1] - self.bias
        if s.method == "constant" or len(t) < 3:
            return newest * h
        dt = float(np.median(np.diff(t)))
        n = round(s.ar_window_s / dt) if dt > 0 else 0
        p = s.ar_order
        if n < 4 * p or self._n < n:
            return newest * h
        t, w = self.rates(n)
        y, c0, slope = _detrend(w, dt)
        last = int(self._t[(self._head - 1) % self.capacity])
        key = self._fit_key
        if key is None or key[1] != n or last - key[0] >= s.ar_refit_s * 1e9:
            self._coef, self._fit_key = _ar_fit(y, p), (last, n)
        got = None if self._coef is None else _ar_run(y, self._coef, dt, h)
        if got is None:
            got = _taylor_forward(w[-max(3, round(s.fallback_window_s / dt)) :], dt, h)
        else:
            got = got + c0 * h + 0.5 * slope * h * h  # the trend c0 + c1 t over [0, h]
        return got - self.bias * h


def _detrend(w: FloatArray, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The rates (n, 3) sampled every ``dt`` less each axis's least-squares straight
    line ``c0 + c1 x`` (x in seconds, 0 at the newest sample): the residuals (n, 3),
    ``c0`` (3,) and ``c1`` (3,)."""
    n = len(w)
    k = np.arange(n) - 0.5 * (n - 1)  # centred sample index
    wm = w.mean(axis=0)
    slope: FloatArray = (k @ w) / (float(k @ k) * dt)
    c0: FloatArray = wm + slope * (0.5 * (n - 1) * dt)
    y: FloatArray = w - wm - np.outer(k * dt, slope)
    return y, c0, slope


def _ar_fit(y: FloatArray, p: int) -> FloatArray | None:
    """Each axis's AR(``p``) least-squares coefficients (3, p) on the residuals (n, 3),
    newest lag first (zero for an axis with nothing to fit); None when a fit is unstable
    (a root of its polynomial beyond ``MAX_ROOT``). The three
    axes are fitted at once: the normal equations from one product of the lagged
    samples, the roots as the eigenvalues of the companion matrices."""
    Z = np.lib.stride_tricks.sliding_window_view(y, p + 1, axis=0)  # (n - p, 3, p + 1)
    M = np.einsum("kai,kaj->aij", Z, Z)  # (3, p + 1, p + 1), oldest lag first
    G = M[:, :p, :p][:, ::-1, ::-1].copy()  # lags newest first
    b = M[:, :p, p][:, ::-1].copy()
    # an axis with no oscillation left in its rate (residuals under a nanoradian per
    # second, rounding; or lagged samples of rank below p, as least squares would rank
    # their singular values) is continued as zero
    ev = np.linalg.eigvalsh(G)  # ascending, (3, p)
    flat = (ev[:, -1] <= len(Z) * FLAT_RATE**2) | (ev[:, 0] <= (1e-15 * len(Z)) ** 2 * ev[:, -1])
    G[flat] = np.eye(p)
    b[flat] = 0.0
    coef: FloatArray = np.linalg.solve(G, b[..., None])[..., 0]
    companion = np.zeros((3, p, p))
    companion[:, 0, :] = coef
    companion[:, np.arange(1, p), np.arange(p - 1)] = 1.0
    if np.abs(np.linalg.eigvals(companion)).max() > MAX_ROOT:
        return None
    return coef


def _ar_run(y: FloatArray, coef: FloatArray, dt: float, h: float) -> FloatArray | None:
    """The integral (3,) over the next ``h`` seconds of the residuals (n, 3) sampled
    every ``dt``, continued by the AR coefficients (3, p); None when the continuation
    leaves 1.5 times the range of the window (a fit that does not fit any more)."""
    p = coef.shape[1]
    steps = int(np.ceil(h / dt - 1e-9))
    c = coef.tolist()
    out = np.empty(3)
    for a in range(3):
        ca = c[a]
        hist = y[-p:, a][::-1].tolist()
        bound = 1.5 * float(np.abs(y[:, a]).max())
        prev = hist[0]
        total = 0.0
        for j in range(steps):
            v = sum(ci * hi for ci, hi in zip(ca, hist, strict=True))
            if abs(v) > bound:
                return None
            width = min(dt, h - j * dt)
            # trapezoids over whole steps, the last one cut at h
            total += 0.5 * (prev + prev + (v - prev) * (width / dt)) * width
            hist = [v, *hist[:-1]]
            prev = v
        out[a] = total
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
