"""A device held in a hand: a smooth path with still phases, plus tremor; and the IMU
samples that motion produces.

Poses are ``T_W_P`` with W = the projector frame at t = 0. The path holds still, makes
a minimum-jerk move to a new aim, holds still again, and so on; physiological tremor
(8-12 Hz) and a slow sway ride on top all the time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rotations import rodrigues

GRAVITY_W = np.array([0.0, 9.80665, 0.0])  # y is down in W (the device starts level)


def _min_jerk(tau: FloatArray) -> FloatArray:
    t = np.clip(tau, 0.0, 1.0)
    return t**3 * (10 - 15 * t + 6 * t * t)


@dataclass(frozen=True)
class HandMotion:
    """Smooth path + tremor over ``seconds``; fully determined by ``seed``.

    Parameters
    ----------
    seconds : float
    seed : int
    move_m, move_rad : size of each deliberate move (translation, rotation)
    tremor_m, tremor_rad : tremor amplitude
    still_s, move_s : durations of the still and moving phases
    """

    seconds: float
    seed: int = 0
    move_m: float = 0.04
    move_rad: float = 0.035
    tremor_m: float = 0.00005
    tremor_rad: float = 0.0002
    still_s: float = 1.0
    move_s: float = 0.8

    def _params(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        rng = np.random.default_rng(self.seed)
        n_moves = int(self.seconds / (self.still_s + self.move_s)) + 2
        aims = rng.normal(size=(n_moves + 1, 6)) * np.r_[[self.move_m] * 3, [self.move_rad] * 3]
        aims[:, 2] *= 0.5  # less motion along the view direction
        aims[0] = 0.0
        freqs = rng.uniform(8.0, 12.0, size=(3, 6))
        phases = rng.uniform(0, 2 * np.pi, size=(3, 6))
        sway = rng.uniform(0, 2 * np.pi, size=6)
        return aims, freqs, phases, sway

    def moving(self, t: FloatArray) -> NDArray[np.bool_]:
        """Whether the deliberate path is moving at times ``t`` (N,) seconds."""
        period = self.still_s + self.move_s
        return np.asarray(np.mod(t, period) >= self.still_s)

    def state(self, t: FloatArray) -> FloatArray:
        """Translation and rotation vector (N, 6) at times ``t`` (N,) seconds."""
        aims, freqs, phases, sway = self._params()
        t = np.asarray(t, dtype=np.float64)
        period = self.still_s + self.move_s
        k = np.floor(t / period).astype(int)
        tau = np.where(t < 0, -1.0, (np.mod(t, period) - self.still_s) / self.move_s)
        s = _min_jerk(tau)[:, None]
        k = np.clip(np.where(t < 0, 0, k), 0, len(aims) - 2)
        x = aims[k] + s * (aims[k + 1] - aims[k])
        amp = np.r_[[self.tremor_m] * 3, [self.tremor_rad] * 3]
        for i in range(3):
            x = x + amp / 3 * np.sin(2 * np.pi * freqs[i] * t[:, None] + phases[i])
        x = x + amp * 3 * np.sin(2 * np.pi * 0.3 * t[:, None] + sway)
        return x  # type: ignore[no-any-return]

    def pose(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``R_W_P`` (N, 3, 3) and ``t_W_P`` (N, 3) at times ``t`` (N,) seconds."""
        x = self.state(t)
        return rodrigues(x[:, 3:]), x[:, :3]

    def imu_truth(self, t: FloatArray, h: float = 1e-3) -> tuple[FloatArray, FloatArray]:
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
