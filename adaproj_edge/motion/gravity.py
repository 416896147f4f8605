"""Which way is up, from the accelerometer and the gyro: gravity in the projector frame P.

At rest the accelerometer measures the specific force, gravity's reaction: a vector
pointing up (about (0, -9.81, 0) in a level device whose y axis points down). In the
hand it measures more: the hand turns the device about the wrist, some 0.3 m behind it,
and a rotational tremor of 0.3 degrees RMS at 10 Hz swings it on that lever by about
``r w^2 theta`` = 6 m/s^2 RMS, against 9.8 m/s^2 of gravity. The gyro knows the
rotation. The estimate is built in three steps:

1. **The lever, taken out.** A point ``rho`` from the centre of rotation accelerates by
   ``alpha x rho + w x (w x rho)`` (``alpha``: the angular acceleration, the gyro's
   derivative). ``rho`` is found by recursive least squares (forgetting ``lever_tau_s``)
   on what the accelerometer measures beyond the current gravity estimate, and that
   acceleration is removed from every sample (one sample late: ``alpha`` is a central
   difference). It removes most of the tremor's swing whatever the lever's length, and
   learns no lever from a device that does not turn (``rho`` stays 0). For the first
   ``warmup_s`` only the lever is learnt.
2. **Fitted in a frame that does not turn.** Each corrected sample is turned by the
   integrated gyro into a frame G fixed in the world (up to the gyro's drift),
   averaged over ``block_s`` and fitted there by a line in time (exponentially
   weighted least squares, memory ``memory_s``): the tremor that is left (7-13 Hz)
   averages out, a deliberate turn does not move gravity in G at all (followed at
   once, by the gyro), and the line's slope is the drift of G: the gyro's zero-rate
   offset. The rate is integrated with its offset: an offset learnt while held still
   is off by up to 0.03 rad/s under 0.5 degrees of tremor and moves as it is learnt,
   while a constant one is a straight drift the fit follows. The caller's learnt
   offset (``offset``) serves as the slope's prior (a ridge of ``drift_prior``
   towards the drift it predicts: the fit starts from it and the samples outweigh
   it within a second or two of use) and in the turn's test below. The slope is
   bounded by ``max_drift``.
3. **Trusted where the device is not being moved.** Samples are weighted down as
   their magnitude departs from gravity (``1 / (1 + (d / shake))^2``: a knock, a
   swing the lever does not explain; beyond ``max_departure`` not used at all: a
   reading clipped at full scale), and not used while the device turns on purpose
   (the gyro rate low-passed by ``rate_tau_s``, over ``max_rate``, and
   ``turn_hold_s`` after) or while the caller says it moves (``still=False``): a
   deliberate move accelerates the device slowly, which no low-pass takes out; nor while the force,
   low-passed in G, departs from the fitted gravity by more than ``shift`` (a hand
   shifting the device sideways hardly turns it, and its slow acceleration tilts the
   force by degrees). The rate's low-pass
   shows a turn late while its acceleration is there from its start, so the blocks
   used in the ``turn_recall_s`` before a turn is seen are taken back out of the fit
   (``recall_s`` before a shift or a move the caller reports; ``hold_s`` after it).
   Meanwhile the gyro carries the estimate, and the gyro's offset, not learnt yet
   on a short session under a strong tremor, tips it by up to a degree a second:
   after a turn the accelerometer is used again as soon as the low-passed rate is
   back under ``max_rate`` (``turn_hold_s``: that low-pass already shows a turn's
   end some 0.3 s late; a further 0.3-s hold left the estimate carried by the gyro
   into the first still moments after a move, 1.2-1.35 degrees off on 4-s hands at
   0.5 degrees of tremor), and only about the rate's lag is taken back before it
   (``turn_recall_s``).

The estimate in P is the fitted line's value now, turned back by the integrated gyro.
The accelerometer's zero-g offset tilts the result directly (10 mg is 0.6 degrees):
a unit's offset must be calibrated for the content to stand upright within a degree.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.motion.prediction import small_rotation
from adaproj_edge.motion.rates import LowPass2

STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class GravitySettings:
    """Tuning of the gravity estimate (seconds, m/s^2, rad/s, metres).

    memory_s : float
        Memory of the trend's weighted least squares in the non-turning frame (the
        weight of a sample falls by ``e`` every ``memory_s``).
    block_s : float
        Samples are averaged over blocks of this length before the fit.
    drift_prior : float
        The fit's ridge on the drift, towards the one the caller's offset predicts (0
        without one; weight-seconds^3: how much the samples must say before they
        outweigh it).
    max_drift : float
        The largest drift believed (rad/s: a gyro offset not learnt yet).
    shake : float
        Magnitude departure from gravity (after the lever is taken out) at which a
        sample's weight is a quarter.
    max_departure : float
        Magnitude departure beyond which a sample is not used at all (m/s^2): what the
        lever does not explain by that much is a reading clipped at the accelerometer's
        full scale (a 0.5-degree tremor swings the device by up to 4 g) or a knock.
    max_rate : float
        Deliberate turning rate (low-passed) over which the accelerometer is not used.
    rate_tau_s : float
        Time constant of each of the two low-passes of that rate (the tremor out).
    hold_s : float
        Seconds after a sideways shift (below) or a move the caller reports before
        the accelerometer is used again (the force's low-pass is quick, and the end
        of the shift's slowing down is still in the samples).
    recall_s : float
        Samples used within this many seconds before such a move is seen are taken
        back out.
    turn_hold_s : float
        Seconds after a deliberate turn (its low-passed rate back under
        ``max_rate``) before the accelerometer is used again (0: at once; that
        low-pass's own lag, some 0.3 s, is the hold).
    turn_recall_s : float
        Samples used within this many seconds before a deliberate turn is seen are
        taken back out (the turn's rate shows late, its acceleration at once: about
        two of ``rate_tau_s`` and the rise to ``max_rate``; at 0.3 s a move's start
        was left in the fit on some hands).
    lever_tau_s : float
        Memory of the lever's least squares (seconds).
    max_lever : float
        The longest lever believed (metres; a longer one is scaled down to it).
    warmup_s : float
        Seconds from the first sample while only the lever is learnt (no sample used;
        the deliberate rate is checked from two of its time constants later).
    settle_s : float
        Seconds of used samples before the estimate is trusted.
    drift_prior_new : float
        The ridge while the caller's offset is learnt from no samples yet (it grows to
        ``drift_prior`` over ``offset_learnt_s`` of them): under a strong tremor the
        offset is learnt slowly and a firm prior towards a wrong one tilts the fit.
    offset_learnt_s : float
        Seconds of samples the offset is learnt from for the full ridge.
    shift : float
        Departure (m/s^2, about 2 degrees' worth) of the corrected force in G,
        low-passed with ``shift_tau_s`` (twice), from the fitted gravity over which the
        device counts as moved without turning (a sideways shift of the hand: its
        acceleration is slow and the lever does not explain it); 0: no such test.
    shift_tau_s : float
        Time constant of each of the two low-passes of that force (the tremor out).
    shift_escape_s : float
        After this long moved so without turning the samples are used again (a fit
        that went wrong is not locked out of its own correction).
    """

    memory_s: float = 4.0
    block_s: float = 0.02
    drift_prior: float = 0.1
    max_drift: float = 0.05
    shake: float = 3.0
    max_departure: float = 3.0
    max_rate: float = 0.04
    rate_tau_s: float = 0.15
    hold_s: float = 0.3
    recall_s: float = 0.5
    turn_hold_s: float = 0.0
    turn_recall_s: float = 0.4
    lever_tau_s: float = 3.0
    max_lever: float = 1.0
    warmup_s: float = 0.3
    settle_s: float = 0.25
    shift: float = 0.4
    drift_prior_new: float = 0.05
    offset_learnt_s: float = 2.0
    shift_tau_s: float = 0.05
    shift_escape_s: float = 2.0


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class _Trend:
    """Exponentially weighted least squares of a 3-vector's line in time, ``x(t) = m +
    v (t - t_ref)``, with ``t_ref`` the newest time; a block can be taken back out."""

    def __init__(self, memory_s: float, drift_prior: float) -> None:
        self.memory_s, self.drift_prior = memory_s, drift_prior
        self.t_ref = 0.0
        self.s = np.zeros(3)  # sum w, sum w tau, sum w tau^2
        self.sx = np.zeros(3)
        self.stx = np.zeros(3)

    def advance(self, t: float) -> None:
        """Move the reference time to ``t`` (later): the sums forget and are rebased."""
        d = t - self.t_ref
        if d <= 0:
            return
        f = math.exp(-d / self.memory_s)
        s0, s1, s2 = self.s * f
        self.s = np.array([s0, s1 - d * s0, s2 - 2 * d * s1 + d * d * s0])
        self.stx = (self.stx - d * self.sx) * f
        self.sx = self.sx * f
        self.t_ref = t

    def add(self, t: float, x: FloatArray, w: float) -> None:
        """Add (``w`` > 0) or take back out (``w`` < 0) a block at time ``t`` <= t_ref."""
        we = w * math.exp(-(self.t_ref - t) / self.memory_s)
        tau = t - self.t_ref
        self.s += we * np.array([1.0, tau, tau * tau])
        self.sx += we * x
        self.stx += we * tau * x

    def at(self, t: float, max_drift: float, spin: FloatArray | None = None) -> FloatArray | None:
        """The line's value (3,) at ``t``; None without weight. ``spin`` (3,) rad/s: the
        turn of the frame the caller expects (the drift's prior: ``spin x x``)."""
        s0, s1, s2 = self.s
        if s0 <= 1e-9:
            return None
        stx = self.stx
        if spin is not None:
            stx = stx + self.drift_prior * np.cross(spin, self.sx / s0)
        s2 += self.drift_prior
        det = s0 * s2 - s1 * s1
        m = (s2 * self.sx - s1 * stx) / det
        v = (s0 * stx - s1 * self.sx) / det
        n = float(np.linalg.norm(m))
        limit = max_drift * n
        vn = float(np.linalg.norm(v))
        if vn > limit:
            v = v * (limit / vn)
        out: FloatArray = m + v * (t - self.t_ref)
        return out


class GravityFilter:
    """Up (unit vector in frame P) from accelerometer and gyro samples in frame P.

    Parameters
    ----------
    settings : GravitySettings
    """

    def __init__(self, settings: GravitySettings | None = None) -> None:
        self.settings = settings or GravitySettings()
        self._rate = LowPass2(self.settings.rate_tau_s)
        self.reset()

    def reset(self) -> None:
        """Forget the estimate (after an IMU fault)."""
        s = self.settings
        self._R = np.eye(3)  # R_G_P: the integrated gyro
        self._trend = _Trend(s.memory_s, s.drift_prior)
        self._first: FloatArray | None = None  # in G, while nothing is fitted
        self._last_ns: int | None = None
        self._used_s = 0.0
        self._prev: tuple[FloatArray, FloatArray, float] | None = None  # accel, rate, dt
        self._prev_rate: FloatArray | None = None
        self._normal = np.eye(3) * 1e-3  # the lever's normal equations
        self._rhs = np.zeros(3)
        self.lever: FloatArray = np.zeros(3)  # rho (3,): centre of rotation -> IMU, metres, frame P
        self._rate.reset()
        self._steps = 0
        self._quiet_s = math.inf  # since the last deliberate turn or shift (none yet)
        self._hold_s = 0.0  # how long the last one holds the accelerometer out after it
        self._age_s = 0.0  # since the first sample
        self._block = np.zeros(5)  # sum w x (3), sum w, sum w t
        self._block_s = 0.0
        self._recent: deque[tuple[float, FloatArray, float]] = deque()  # used blocks
        self._offset: FloatArray | None = None  # the caller's gyro offset, frame P
        self._slow = LowPass2(self.settings.shift_tau_s)  # the corrected force in G
        self._slow_started = False
        self._shifted_s = 0.0

    def update(
        self,
        t_ns: int,
        accel: FloatArray,
        rate: FloatArray,
        still: bool = True,
        offset: FloatArray | None = None,
        offset_s: float | None = None,
    ) -> None:
        """One sample: specific force (3,) m/s^2 and angular rate (3,) rad/s, frame P;
        ``still``: whether the caller sees the device held still (else the accelerometer
        is not used, the gyro carries the estimate); ``offset`` (3,) rad/s: the gyro's
        zero-rate offset as the caller knows it (``offset_s``: from how many seconds
        of samples; the prior's ridge grows with it), taken out of the rate for the
        deliberate turn's test only (the integrated rate keeps it: a constant offset is
        a drift the fit follows, a learnt one that moves is not)."""
        s = self.settings
        a = np.asarray(accel, dtype=np.float64)
        w = np.asarray(rate, dtype=np.float64)
        dt = 0.0 if self._last_ns is None else max(0.0, (t_ns - self._last_ns) * 1e-9)
        self._last_ns = t_ns
        if dt > 0.1:  # a gap: the lever's difference and the samples held are stale
            self._prev = self._prev_rate = None
            self._block[:] = 0.0
            self._block_s = 0.0
            self._slow_started = False
            dt = 0.1
        if offset is not None:
            self._offset = np.asarray(offset, dtype=np.float64)
        if offset_s is not None:  # the prior as firm as the offset is learnt
            k = min(1.0, max(0.0, offset_s) / s.offset_learnt_s)
            self._trend.drift_prior = s.drift_prior_new + (s.drift_prior - s.drift_prior_new) * k
        if dt > 0:
            self._R = self._R @ small_rotation(w * dt)
            self._rate.update(w if offset is None else w - np.asarray(offset, np.float64), dt)
            self._steps += 1
            if self._steps % 512 == 0:  # keep R a rotation
                u, _, vt = np.linalg.svd(self._R)
                self._R = u @ vt
        # samples k-1 (accel, rate, dt) and k-2 (rate) kept: sample k-1 is used now
        prev, prev_rate = self._prev, self._prev_rate
        self._prev = (a, w, dt)
        self._prev_rate = None if prev is None else prev[1]
        if prev is None or prev_rate is None or dt <= 0 or prev[2] <= 0:
            if self._first is None and prev is None:
                self._first = self._R @ a
            return
        # the previous sample, its angular acceleration a central difference
        a_prev, w_prev, dt_prev = prev
        alpha = (w - prev_rate) / (dt + dt_prev)
        f = self._unlevered(a_prev, w_prev, alpha, dt_prev)
        self._age_s += dt_prev
        t_prev = self._age_s
        if self._age_s < s.warmup_s:
            # the lever is being learnt (its swing still in the samples); the rate's
            # low-pass starts with a transient of the tremor (not checked for two of its
            # time constants more)
            return
        settling = self._age_s < s.warmup_s + 2.0 * s.rate_tau_s  # the low-pass's start
        turning = not settling and float(np.linalg.norm(self._rate.value)) > s.max_rate
        # R_G_P one sample ago: this sample's rotation undone
        x = (self._R @ small_rotation(-w * dt)) @ f
        dev = abs(float(np.linalg.norm(f)) - STANDARD_GRAVITY) / s.shake
        shifted = self._shifted(x, dev * s.shake <= s.max_departure, dt_prev, turning)
        if not still or turning or shifted:
            self._quiet_s = 0.0
            # a turn's rate is low-passed: it shows late, and its end later still
            just_turning = still and not shifted
            self._hold_s = s.turn_hold_s if just_turning else s.hold_s
            self._recall(t_prev - (s.turn_recall_s if just_turning else s.recall_s))
            self._block[:] = 0.0
            self._block_s = 0.0
            return
        self._quiet_s += dt_prev
        if self._quiet_s < self._hold_s:
            return
        # beyond max_departure, not gravity and a swing (a reading clipped at full
        # scale, a knock): not used
        weight = 0.0 if dev * s.shake > s.max_departure else dt_prev / (1.0 + dev) ** 2
        self._block[:3] += weight * x
        self._block[3] += weight
        self._block[4] += weight * t_prev
        self._block_s += dt_prev
        if self._block_s >= s.block_s:
            self._flush()

    def _shifted(self, x: FloatArray, usable: bool, dt: float, turning: bool) -> bool:
        """Whether the force in G (``x`` (3,), low-passed) departs from the fitted
        gravity by more than ``shift``: the device is being moved without turning."""
        s = self.settings
        if usable:
            if not self._slow_started:
                self._slow.update(x, s.shift_tau_s)
                self._slow.update(x, s.shift_tau_s)
                self._slow_started = True
            self._slow.update(x, dt)
        if s.shift <= 0 or not self.ready or not self._slow_started:
            return False
        g = self._trend.at(self._age_s, s.max_drift, self._spin())
        if g is None:
            return False
        if float(np.linalg.norm(self._slow.value - g)) <= s.shift or turning:
            self._shifted_s = 0.0
            return False
        self._shifted_s += dt
        if self._shifted_s > s.shift_escape_s:
            return False
        return True

    def _flush(self) -> None:
        wsum = float(self._block[3])
        if wsum > 0:
            t = float(self._block[4]) / wsum
            x = self._block[:3] / wsum
            self._trend.advance(self._age_s)
            self._trend.add(t, x, wsum)
            self._recent.append((t, x, wsum))
            self._used_s += wsum
        self._block[:] = 0.0
        self._block_s = 0.0
        keep = max(self.settings.recall_s, self.settings.turn_recall_s)
        while self._recent and self._recent[0][0] < self._age_s - keep:
            self._recent.popleft()

    def _recall(self, since: float) -> None:
        """Take the blocks used after ``since`` (seconds of age) back out (all of them:
        the estimate before them is kept)."""
        before = self._trend.at(self._age_s, self.settings.max_drift)
        while self._recent and self._recent[-1][0] >= since:
            t, x, w = self._recent.pop()
            self._trend.add(t, x, -w)
            self._used_s -= w
        if self._used_s < 1e-9:
            self._used_s = 0.0
            if before is not None:
                self._first = before
            self._trend.s[:] = 0.0
            self._trend.sx[:] = 0.0
            self._trend.stx[:] = 0.0

    def _unlevered(self, f: FloatArray, w: FloatArray, alpha: FloatArray, dt: float) -> FloatArray:
        """``f`` with the swing about the centre of rotation taken out; the lever's
        least squares updated with it."""
        s = self.settings
        A = _skew(alpha) + _skew(w) @ _skew(w)  # the acceleration of rho: A @ rho
        up = self.up
        if up is not None:
            resid = f - up * STANDARD_GRAVITY
            forget = math.exp(-dt / s.lever_tau_s)
            self._normal = forget * self._normal + A.T @ A
            self._rhs = forget * self._rhs + A.T @ resid
            lever = np.asarray(
                np.linalg.solve(self._normal + np.eye(3) * 1e-3, self._rhs), np.float64
            )
            n = float(np.linalg.norm(lever))
            self.lever = lever if n <= s.max_lever else lever * float(s.max_lever / n)
        out: FloatArray = f - A @ self.lever
        return out

    def _spin(self) -> FloatArray | None:
        """The drift of G the caller's offset predicts (its turn, in G), if given."""
        if self._offset is None:
            return None
        out: FloatArray = self._R @ self._offset
        return out

    @property
    def ready(self) -> bool:
        """Whether enough samples have been used to trust :attr:`up`."""
        return self._used_s >= self.settings.settle_s

    @property
    def up(self) -> FloatArray | None:
        """Up (3,) as a unit vector in frame P, None before any sample."""
        g = self._trend.at(self._age_s, self.settings.max_drift, self._spin())
        if g is None:
            g = self._first
        if g is None:
            return None
        g = self._R.T @ g
        n = float(np.linalg.norm(g))
        return None if n == 0.0 else g / n
