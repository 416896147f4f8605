"""The accelerometer's zero-g offset: the sphere fit of still poses, the calibration
field that carries it, the runtime that takes it out, and the simulator's calibration
that records it."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from adaproj_edge.app.upright_score import trace_upright, wall_normal
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.rotations import rotation_matrix
from adaproj_edge.procam.accel import solve_accel_offset
from adaproj_edge.session.accel_calibration import session_accel_offset
from adaproj_edge.session.hand import GRAVITY_W, HandMotion
from adaproj_edge.session.simulator import (
    ImuNoise,
    SimulationSettings,
    imu_readings,
    recorded_calibration,
)

G = float(np.linalg.norm(GRAVITY_W))


def _poses(offset: np.ndarray, rng: np.random.Generator, n: int, turn_deg: float, sigma: float):
    """Mean readings (n, 3) of still poses turned ``turn_deg`` RMS from level, and the
    mean direction of their specific force."""
    ups = np.array(
        [rotation_matrix(np.radians(rng.normal(scale=turn_deg, size=3))).T @ [0.0, -1.0, 0.0]
         for _ in range(n)]
    )  # fmt: skip
    a = 9.79 * ups + offset + rng.normal(scale=sigma, size=(n, 3))
    m = ups.mean(axis=0)
    return a, m / np.linalg.norm(m)


@pytest.mark.parametrize("seed", range(5))
def test_the_sphere_fit_finds_the_offset_that_tilts_up(seed: int) -> None:
    rng = np.random.default_rng(seed)
    offset = rng.normal(scale=0.1, size=3)
    sigma = 0.002  # a second's mean reading
    a, m = _poses(offset, rng, 8, 25.0, sigma)
    fit = solve_accel_offset(a)
    assert fit.measured, fit.problem
    err = fit.offset - offset
    across = err - (err @ m) * m
    # across the mean reading (what tilts up) the error is the readings' noise divided
    # by the poses' spread (~25 deg: a factor ~3); 5 sigma of that, 1.5 mg
    assert np.linalg.norm(across) < 5 * sigma * 3 / 2, (err, fit)
    # the local gravity (9.79, not standard) is taken up by g, not by the offset
    assert abs(fit.gravity - 9.79) < 0.05
    # a tenth of a degree of tilt at most, where the offset was up to a degree
    assert np.degrees(np.linalg.norm(across) / G) < 0.1


def test_the_fit_refuses_poses_it_cannot_use() -> None:
    up = np.array([0.0, -G, 0.0])
    assert not solve_accel_offset(np.array([up, up])).measured  # two poses
    flat = solve_accel_offset(np.array([up, up * 1.0001, up * 0.9999]))
    assert not flat.measured and "turn" in flat.problem  # one orientation
    assert not solve_accel_offset(np.array([up, up / 2, -up])).measured  # not 1 g
    assert not solve_accel_offset(np.array([up, [np.nan, 0, 0], -up])).measured
    assert np.array_equal(flat.offset, np.zeros(3))


def test_the_offset_round_trips_and_bad_values_are_refused() -> None:
    cal = Calibration.default()
    assert "imu" not in cal.to_dict()  # old files and attachments are unchanged
    b = np.array([0.05, -0.12, 0.031])
    with_b = Calibration(cal.projector, cal.depth, cal.T_P_D, cal.R_P_I, accel_offset=b)
    for back in (
        Calibration.from_json(with_b.to_json()),
        Calibration.from_dict(tomllib.loads(with_b.to_toml())),
    ):
        assert np.array_equal(back.accel_offset, b)
    data = with_b.to_dict()
    for bad, says in (
        ([0.0, 0.0], "accel_offset"),
        ([0.0, 5.0, 0.0], "accel_offset[1]"),
        ([0.0, float("nan"), 0.0], "accel_offset[1]"),
        (["x", 0.0, 0.0], "accel_offset[0]"),
        ("0 0 0", "accel_offset"),
    ):
        data["imu"] = {"accel_offset": bad}
        with pytest.raises(InputError, match=r"\[imu\] " + says.replace("[", r"\[")):
            Calibration.from_dict(data, "cal.toml")
    data["imu"] = {"accel_offset": [0.0, 0.0, 0.0], "gyro": 1}
    with pytest.raises(InputError, match="unknown keys"):
        Calibration.from_dict(data, "cal.toml")


def test_the_simulated_offset_is_the_streams_first_draw() -> None:
    """The simulator's calibration estimates the offset the session's IMU has: the
    first draw of its stream (checked on a still, noise-free IMU against the truth)."""
    hand = HandMotion(0.3, seed=3, tremor_deg=0.0, sway_deg=0.0, move_rad=0.0, move_m=0.0)
    noise = ImuNoise(accel_density=0.0, gyro_density=0.0)
    sim = SimulationSettings(seconds=0.3, seed=3, motion=hand, imu_noise=noise)
    cal = Calibration.default()
    _, acc, _ = imu_readings(hand, cal.R_P_I, sim, np.random.default_rng(3))
    f_p, _ = hand.imu_truth(np.arange(acc.shape[0]) / sim.imu.rate_hz)
    measured = (acc - f_p @ cal.R_P_I).mean(axis=0)
    lsb = sim.imu.accel_scale  # quantisation: half an LSB per sample at most
    assert np.allclose(measured, session_accel_offset(3, noise.accel_bias_sigma), atol=lsb)
    # and the recorded calibration is within the drift of it (4 sigma per axis)
    recorded = recorded_calibration(cal, sim).accel_offset
    assert np.all(np.abs(recorded - measured) < 4 * noise.accel_offset_drift + lsb)
    off = SimulationSettings(seconds=0.3, seed=3, accel_calibrated=False)
    assert np.array_equal(recorded_calibration(cal, off).accel_offset, np.zeros(3))


def test_a_calibrated_offset_keeps_a_level_wall_upright() -> None:
    """The up chain with the simulator's calibration against the hand's true gravity:
    the offset (10 mg RMS; seed 3's tilts up by 1.8 deg) no longer tilts it."""
    hand = HandMotion(4.0, seed=3, tremor_deg=0.05, roll_deg=12.0)
    n = wall_normal(0.0)
    raw = trace_upright(hand, 3, calibrated=False)
    cal = trace_upright(hand, 3)
    assert raw.error_deg(n)[raw.still].max() > 1.0  # the defect, as it was
    assert cal.error_deg(n)[cal.still].max() < 1.0
