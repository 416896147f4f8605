"""The accelerometer offset a simulated device's calibration carries.

A real unit's calibration (``adaproj calibrate``) measures its accelerometer's zero-g
offset from the still poses (:mod:`~adaproj_edge.procam.accel`); a simulated session
records a calibration too, and without that field the simulated IMU's offset (10 mg
RMS per axis, :class:`~adaproj_edge.session.simulator.ImuNoise`) tilted every gravity
estimate by up to a degree that a calibrated unit does not have. Here the
calibration's still poses are simulated for the session's IMU (its offset, the
readings' noise averaged over a second, the chip's quantisation; the device pointed
at a wall, turned some 25 degrees between poses, as the procedure asks) and fitted by
the same sphere fit; the offset then moves by ``ImuNoise.accel_offset_drift`` (the
temperature between the calibration and the session), so a simulated device keeps the
error a calibrated unit has.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.rotations import rotation_matrix
from adaproj_edge.procam.accel import solve_accel_offset
from adaproj_edge.session.hand import GRAVITY_W

POSES = 8
"""Still poses of the simulated calibration."""
TURN_DEG = 25.0
"""How far (RMS per axis) the poses turn from pointing level at the wall."""
POSE_S = 1.0
"""Seconds of readings averaged per pose."""
STREAM = 34
"""Mixed into the seed: the calibration's draws never touch the session's stream."""


def session_accel_offset(seed: int, sigma: float) -> FloatArray:
    """The accelerometer offset (3,) m/s^2 in frame I of the session simulated with
    ``seed`` and offset sigma ``sigma``: the first draw of the session's random stream
    (:func:`~adaproj_edge.session.simulator.imu_readings` draws it first)."""
    out: FloatArray = np.random.default_rng(seed).normal(scale=sigma, size=3)
    return out


def calibrated_offset(
    offset: FloatArray,
    R_P_I: FloatArray,
    seed: int,
    noise_sigma: float,
    lsb: float,
    drift: float,
    rate_hz: float,
) -> FloatArray:
    """What the calibration of an IMU with zero-g ``offset`` (3,) (frame I, m/s^2)
    records, ``drift`` (m/s^2 RMS per axis) before the session: the sphere fit of
    :data:`POSES` simulated still poses' mean readings (per-sample noise
    ``noise_sigma`` at ``rate_hz``, quantised to ``lsb``), drawn from ``seed``."""
    rng = np.random.default_rng([seed, STREAM])
    at_calibration = np.asarray(offset, dtype=np.float64) - rng.normal(scale=drift, size=3)
    R_I_P = np.asarray(R_P_I, dtype=np.float64).T
    n = max(round(POSE_S * rate_hz), 1)
    means = []
    for _ in range(POSES):
        R_W_P = rotation_matrix(np.radians(rng.normal(scale=TURN_DEG, size=3)))
        f_i = R_I_P @ (R_W_P.T @ -GRAVITY_W) + at_calibration
        reads = f_i + rng.normal(scale=noise_sigma, size=(n, 3))
        means.append((np.round(reads / lsb) * lsb).mean(axis=0))
    fit = solve_accel_offset(np.array(means))
    return fit.offset if fit.measured else np.zeros(3)


def with_accel_offset(
    calibration: Calibration,
    seed: int,
    bias_sigma: float,
    noise_sigma: float,
    lsb: float,
    drift: float,
    rate_hz: float,
) -> Calibration:
    """``calibration`` carrying the offset its calibration would have measured on the
    IMU of the session simulated with ``seed`` (offset sigma ``bias_sigma``); unchanged
    when it carries an offset already."""
    if np.any(calibration.accel_offset):
        return calibration
    true = session_accel_offset(seed, bias_sigma)
    est = calibrated_offset(true, calibration.R_P_I, seed, noise_sigma, lsb, drift, rate_hz)
    return replace(calibration, accel_offset=est)
