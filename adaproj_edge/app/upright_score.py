"""The content's "up" scored on a simulated hand without the warp pipeline.

The runtime's chain from IMU samples to the warps' up (the motion tracker's gyro
bias, :class:`~adaproj_edge.motion.upright.Upright`) is fed the samples the
simulator's IMU would report of a :class:`~adaproj_edge.session.hand.HandMotion`
(noise, offsets and quantisation included; no depth frames, no warps). Each up is
turned into the world with the hand's rotation *without its tremor* (what the
stabilised picture shows: the stabiliser cancels the tremor and follows the rest) and
compared, on a plane of normal ``n``, with gravity projected on that plane: the angle
between the content's vertical and the true one on a wall of that orientation. A few
milliseconds of CPU per simulated second: the gravity part of the hand-held figures
can be swept over many seeds, tremors and rolls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adaproj_edge.app.handheld import AFTER_MOVE_S
from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.motion.tracker import MotionSettings, MotionTracker
from adaproj_edge.motion.upright import Upright, UprightSettings
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.simulator import (
    ImuNoise,
    SimulationSettings,
    imu_readings,
    recorded_calibration,
)
from adaproj_edge.warp.placement import DEFAULT_UP

T0_NS = 1_000_000_000
UP_W = np.array([0.0, -1.0, 0.0])  # up in the world frame W (y down)


@dataclass(frozen=True)
class UprightTrace:
    """The content's up over a simulated hand: times (N,) seconds, up (N, 3) in P,
    the hand's tremor-free rotation (N, 3, 3) and whether the user holds still (N,)."""

    t: FloatArray
    up: FloatArray
    R_steady: FloatArray
    still: np.ndarray

    def error_deg(self, normal_w: FloatArray) -> FloatArray:
        """The angle (N,) between the content's vertical and gravity's on a plane of
        unit normal ``normal_w`` (3,) in W (degrees)."""
        n = np.asarray(normal_w, dtype=np.float64)
        n = n / np.linalg.norm(n)
        u = np.einsum("nij,nj->ni", self.R_steady, self.up)
        u -= np.outer(u @ n, n)
        g = UP_W - np.dot(UP_W, n) * n
        cos = (u @ g) / (np.linalg.norm(u, axis=1) * np.linalg.norm(g))
        out: FloatArray = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        return out


def trace_upright(
    hand: HandMotion,
    seed: int,
    noise: ImuNoise | None = None,
    calibration: Calibration | None = None,
    upright: UprightSettings | None = None,
    motion: MotionSettings | None = None,
    every: int = 7,
    from_s: float = 0.9,
    calibrated: bool = True,
) -> UprightTrace:
    """Feed the runtime's up chain the IMU samples of ``hand`` (offsets and noise drawn
    from ``seed`` as the session simulator does) and keep the up every ``every``
    samples from ``from_s`` seconds (when a session's first warp is shown).

    ``calibration``: the device's (its accelerometer offset is taken out of every
    reading, as the runtime does); by default the nominal one with the offset the
    simulator records (``calibrated``: measured by a calibration, else none)."""
    sim = SimulationSettings(
        seconds=hand.seconds, seed=seed, motion=hand, imu_noise=noise or ImuNoise(),
        accel_calibrated=calibrated,
    )  # fmt: skip
    cal = calibration or recorded_calibration(Calibration.default(), sim)
    t, acc, gyr = imu_readings(hand, cal.R_P_I, sim, np.random.default_rng(seed))
    tracker = MotionTracker(cal.R_P_I, motion)
    chain = Upright(upright)
    R = cal.R_P_I
    keep_t: list[float] = []
    keep_up: list[FloatArray] = []
    default = np.asarray(DEFAULT_UP, dtype=np.float64)
    for i in range(len(t)):
        ts = T0_NS + round(t[i] * 1e9)
        sample = ImuSample(ts, ts, tuple(acc[i]), tuple(gyr[i]), 30.0)
        tracker.update(sample)
        bias = tracker.bias
        chain.update(
            ts, R @ (acc[i] - cal.accel_offset), R @ gyr[i], True, R @ bias.value, bias.learnt_s
        )
        if i % every == 0 and t[i] >= from_s:
            up = chain.up
            keep_t.append(float(t[i]))
            keep_up.append(default if up is None else up)
    tt = np.array(keep_t)
    still = np.zeros(len(tt), dtype=bool)
    for a, b in hand.still_intervals():
        skip = AFTER_MOVE_S if a > 0 else 0.0
        still |= (tt >= a + skip) & (tt < b)
    if hand.roll_move_deg:
        moving = (tt >= hand.roll_move_at_s) & (tt < hand.roll_move_at_s + hand.roll_move_s)
        still &= ~moving
    return UprightTrace(tt, np.array(keep_up), hand.steady_rotation(tt), still)


def wall_normal(yaw_deg: float) -> FloatArray:
    """The normal (3,) in W of a wall facing the device, turned ``yaw_deg`` about the
    vertical."""
    y = np.radians(yaw_deg)
    return np.array([np.sin(y), 0.0, -np.cos(y)])
