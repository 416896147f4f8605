"""A device held in a hand: a smooth path with still phases, plus tremor and a slow
sway; and the IMU samples that motion produces.

Poses are ``T_W_P``. W is an upright world frame (y down, along gravity) whose origin
and heading are the projector's at t = 0; a device held rolled by ``roll_deg`` (about
its optical axis) starts rolled in W, so the scene stands upright in W whatever the
roll.

The path holds still, makes a minimum-jerk move to a new aim, holds still again, and
so on (the user's intent). On top, all the time:

- **tremor**: physiological hand tremor, a narrow band around a peak frequency drawn
  between 8.5 and 11 Hz (Gaussian, 1 Hz standard deviation, within 7-13 Hz), as a sum
  of many sinusoids with random phases (Gaussian noise of that spectrum), ``tremor_deg``
  RMS about each axis and ``tremor_m`` RMS along each;
- **sway**: the slow drift of a hand trying to hold still, 0.1-1 Hz with a
  1/sqrt(f) amplitude spectrum, ``sway_deg`` RMS about each axis (and ``tremor_m``
  times 5 along each).

Every rotation (the moves, the tremor, the sway) turns the device about the wrist,
``lever_m`` behind it along its optical axis, not about its own centre: the device
swings on that lever, and its accelerometer feels it. At 0.3 degrees RMS of 10 Hz
tremor and 0.3 m, that is about r w^2 theta = 6 m/s^2 RMS across the lever, against
9.8 m/s^2 of gravity: the accelerometer alone is a poor gravity sensor in the hand
(``lever_m = 0`` turns the device about its centre, as before).

Everything follows from ``seed``; the spectra are continuous functions of time, so
the true pose is known at any instant (e.g. when a frame is lit).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rotations import rodrigues, rotation_matrix

GRAVITY_W = np.array([0.0, 9.80665, 0.0])  # y is down in W (an upright world)
TREMOR_COMPONENTS = 48
SWAY_COMPONENTS = 16


def _min_jerk(tau: FloatArray) -> FloatArray:
    t = np.clip(tau, 0.0, 1.0)
    return t**3 * (10 - 15 * t + 6 * t * t)


@dataclass(frozen=True)
class _Spectrum:
    """A sum of sinusoids per channel: frequencies (K, 6) Hz, phases (K, 6), amplitudes
    (K, 6); channel RMS = sqrt(sum(amplitude^2) / 2)."""

    freqs: FloatArray
    phases: FloatArray
    amps: FloatArray

    def value(self, t: FloatArray) -> FloatArray:
        """(N, 6) at times (N,)."""
        arg = 2 * np.pi * self.freqs[None] * t[:, None, None] + self.phases[None]
        out: FloatArray = np.sum(self.amps[None] * np.sin(arg), axis=1)
        return out


def _scaled(amps: FloatArray, rms: FloatArray) -> FloatArray:
    """Amplitudes (K, 6) scaled so each channel has the RMS ``rms`` (6,)."""
    now = np.sqrt(np.sum(amps**2, axis=0) / 2)
    out: FloatArray = amps * (rms / np.where(now > 0, now, 1.0))
    return out


@dataclass(frozen=True)
class HandMotion:
    """Smooth path + tremor + sway over ``seconds``; fully determined by ``seed``.

    Parameters
    ----------
    seconds : float
    seed : int
    move_m, move_rad : size of each deliberate move (translation, rotation)
    tremor_deg : RMS tremor rotation about each axis (degrees)
    tremor_m : RMS tremor translation along each axis (metres)
    sway_deg : RMS slow sway about each axis (degrees)
    roll_deg : the device's roll about its optical axis, held the whole time
    roll_move_deg, roll_move_at_s, roll_move_s : float
        A deliberate roll about the optical axis by ``roll_move_deg`` (minimum jerk),
        starting at ``roll_move_at_s`` and lasting ``roll_move_s`` (0: none)
    lever_m : distance from the wrist (the centre of every rotation) to the device,
        along the device's optical axis (metres)
    still_s, move_s : durations of the still and moving phases
    hold_after : int, optional
        After this many moves the hand holds still to the end (None: never).
    """

    seconds: float
    seed: int = 0
    move_m: float = 0.04
    move_rad: float = 0.035
    tremor_deg: float = 0.005
    tremor_m: float = 0.00002
    sway_deg: float = 0.025
    roll_deg: float = 0.0
    roll_move_deg: float = 0.0
    roll_move_at_s: float = 0.0
    roll_move_s: float = 0.5
    lever_m: float = 0.3
    still_s: float = 1.0
    move_s: float = 0.8
    hold_after: int | None = None

    @cached_property
    def _params(self) -> tuple[FloatArray, _Spectrum, _Spectrum]:
        rng = np.random.default_rng(self.seed)
        n_moves = int(self.seconds / (self.still_s + self.move_s)) + 2
        aims = rng.normal(size=(n_moves + 1, 6)) * np.r_[[self.move_m] * 3, [self.move_rad] * 3]
        aims[:, 2] *= 0.5  # less motion along the view direction
        aims[0] = 0.0
        peak = rng.uniform(8.5, 11.0)
        k = TREMOR_COMPONENTS
        tf = np.clip(rng.normal(peak, 1.0, size=(k, 6)), 7.0, 13.0)
        tremor_rms = np.r_[[self.tremor_m] * 3, [np.deg2rad(self.tremor_deg)] * 3]
        tremor = _Spectrum(
            tf, rng.uniform(0, 2 * np.pi, (k, 6)), _scaled(rng.rayleigh(1.0, (k, 6)), tremor_rms)
        )
        k = SWAY_COMPONENTS
        sf = np.exp(rng.uniform(np.log(0.1), np.log(1.0), size=(k, 6)))
        sway_rms = np.r_[[self.tremor_m * 5] * 3, [np.deg2rad(self.sway_deg)] * 3]
        sa = rng.rayleigh(1.0, (k, 6)) / np.sqrt(sf)
        sway = _Spectrum(sf, rng.uniform(0, 2 * np.pi, (k, 6)), _scaled(sa, sway_rms))
        return aims, tremor, sway

    def moving(self, t: FloatArray) -> NDArray[np.bool_]:
        """Whether the deliberate path is moving at times ``t`` (N,) seconds."""
        period = self.still_s + self.move_s
        t = np.asarray(t, dtype=np.float64)
        out = np.mod(t, period) >= self.still_s
        if self.hold_after is not None:
            out &= t < self.hold_after * period
        return np.asarray(out)

    def still_intervals(self) -> list[tuple[float, float]]:
        """The (start, end) seconds of each still phase of the deliberate path."""
        period = self.still_s + self.move_s
        out = []
        start = 0.0
        k = 0
        while start < self.seconds:
            held = self.hold_after is not None and k >= self.hold_after
            end = self.seconds if held else min(start + self.still_s, self.seconds)
            out.append((start, end))
            start += period
            k += 1
            if held:
                break
        return out

    def intent(self, t: FloatArray) -> FloatArray:
        """The deliberate path alone: translation and rotation vector (N, 6)."""
        aims = self._params[0]
        t = np.asarray(t, dtype=np.float64)
        period = self.still_s + self.move_s
        k = np.floor(t / period).astype(int)
        tau = np.where(t < 0, -1.0, (np.mod(t, period) - self.still_s) / self.move_s)
        s = _min_jerk(tau)[:, None]
        k = np.clip(np.where(t < 0, 0, k), 0, len(aims) - 2)
        out: FloatArray = aims[k] + s * (aims[k + 1] - aims[k])
        if self.hold_after is not None:
            held = t >= self.hold_after * period
            out[held] = aims[min(self.hold_after, len(aims) - 1)]
        return out

    def state(self, t: FloatArray) -> FloatArray:
        """Translation and rotation vector (N, 6) at times ``t`` (N,) seconds: the
        deliberate path, the tremor and the sway."""
        _, tremor, sway = self._params
        t = np.asarray(t, dtype=np.float64)
        out: FloatArray = self.intent(t) + tremor.value(t) + sway.value(t)
        return out

    @property
    def R_roll(self) -> FloatArray:
        """The device's roll at the start (3, 3): rotation about its optical axis (z)."""
        return rotation_matrix(np.array([0.0, 0.0, np.deg2rad(self.roll_deg)]))

    def roll(self, t: FloatArray) -> FloatArray:
        """The device's roll (N, 3, 3) at times ``t`` (N,): the start's, then the
        deliberate roll (if any)."""
        t = np.asarray(t, dtype=np.float64)
        tau = (t - self.roll_move_at_s) / max(self.roll_move_s, 1e-9)
        deg = self.roll_deg + self.roll_move_deg * _min_jerk(tau)
        z = np.zeros((len(t), 3))
        z[:, 2] = np.deg2rad(deg)
        return rodrigues(z)

    def steady_rotation(self, t: FloatArray) -> FloatArray:
        """``R_W_P`` (N, 3, 3) without the tremor: what a stabiliser lets through."""
        _, _, sway = self._params
        t = np.asarray(t, dtype=np.float64)
        x = self.intent(t) + sway.value(t)
        out: FloatArray = self.roll(t) @ rodrigues(x[:, 3:])
        return out

    def pose(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``R_W_P`` (N, 3, 3) and ``t_W_P`` (N, 3) at times ``t`` (N,) seconds.

        The rotation turns the device about the wrist (``lever_m`` behind it): the
        wrist stays at the translation part of :meth:`state` plus its rest offset, the
        device at the end of the lever."""
        x = self.state(t)
        R: FloatArray = self.roll(t) @ rodrigues(x[:, 3:])
        wrist_p = np.array([0.0, 0.0, -self.lever_m])  # the wrist, in P
        p: FloatArray = x[:, :3] + self.R_roll @ wrist_p - R @ wrist_p
        return R, p

    def imu_truth(self, t: FloatArray, h: float = 5e-4) -> tuple[FloatArray, FloatArray]:
        """Specific force (N, 3) m/s^2 and angular rate (N, 3) rad/s, both in frame P."""
        t = np.asarray(t, dtype=np.float64)
        R0, p0 = self.pose(t)
        Rm, pm = self.pose(t - h)
        Rp, pp = self.pose(t + h)
        a_w = (pp - 2 * p0 + pm) / h**2
        f_p = np.einsum("nji,nj->ni", R0, a_w - GRAVITY_W)
        d = np.einsum("nji,njk->nik", Rm, Rp)  # R(t-h)^T R(t+h) = exp(2h [w]x)
        w = np.stack(
            [d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], -1
        )
        return f_p, w / (4 * h)
