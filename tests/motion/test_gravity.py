"""The gravity filter: up in frame P from the accelerometer, carried by the gyro."""

from __future__ import annotations

import numpy as np

from adaproj_edge.geometry.rotations import rotation_matrix
from adaproj_edge.motion.gravity import STANDARD_GRAVITY, GravityFilter

RATE_HZ = 416.0


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def test_a_rolled_still_device_finds_up_despite_noise() -> None:
    rng = np.random.default_rng(0)
    roll = np.radians(12.0)
    # up in P for a device rolled about its optical axis: gravity's reaction
    up_true = rotation_matrix(np.array([0.0, 0.0, roll])).T @ np.array([0.0, -1.0, 0.0])
    f = GravityFilter()
    assert f.up is None and not f.ready
    for k in range(int(2 * RATE_HZ)):
        a = up_true * STANDARD_GRAVITY + rng.normal(scale=0.3, size=3)
        f.update(int(k * 1e9 / RATE_HZ), a, rng.normal(scale=0.05, size=3))
    assert f.ready and f.up is not None
    assert _angle(f.up, up_true) < 0.3


def test_the_estimate_turns_with_the_device_between_accelerometer_updates() -> None:
    f = GravityFilter()
    up0 = np.array([0.0, -1.0, 0.0])
    f.update(0, up0 * STANDARD_GRAVITY, np.zeros(3))
    w = np.array([0.0, 0.0, 1.0])  # rolling at 1 rad/s: faster than the filter uses
    dt = 1 / RATE_HZ
    for k in range(1, int(0.3 * RATE_HZ)):
        f.update(int(k * dt * 1e9), np.array([0.0, 0.0, 30.0]), w)  # unusable accel
    R = rotation_matrix(w * (int(0.3 * RATE_HZ) - 1) * dt)
    assert f.up is not None and _angle(f.up, R.T @ up0) < 0.05


def test_accelerations_far_from_gravity_are_not_used_and_reset_forgets() -> None:
    f = GravityFilter()
    f.update(0, np.array([0.0, -20.0, 0.0]), np.zeros(3))
    assert f.up is None
    f.update(1_000_000, np.array([0.0, -STANDARD_GRAVITY, 0.0]), np.zeros(3))
    assert f.up is not None
    f.reset()
    assert f.up is None
