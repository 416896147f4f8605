"""The session simulator: determinism, IMU consistent with the motion, stereo errors."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from adaproj_edge.cli import main
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.rotations import quaternion, rotation_of
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session.hand import GRAVITY_W, HandMotion
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate
from adaproj_edge.session.stereo import StereoNoise, stereo_depth

CAL = Calibration.default()
SHORT = SimulationSettings(seconds=1.0, depth_fps=3.0, seed=4)


def test_same_seed_same_session_other_seed_other_session() -> None:
    scene = Scene.load("tilted")
    a = simulate(scene, CAL, SHORT)
    b = simulate(scene, CAL, SHORT)
    c = simulate(scene, CAL, SimulationSettings(seconds=1.0, depth_fps=3.0, seed=5))
    assert a == b and a != c
    assert [r.receive_ns for r in a] == sorted(r.receive_ns for r in a)


def test_simulated_session_round_trips_exactly(tmp_path: Path) -> None:
    out = tmp_path / "s.mcap"
    assert main(["simulate-session", "--surface", "corner", "--seconds", "1", "--depth-fps",
                 "3", "--seed", "4", "--out", str(out)]) == 0  # fmt: skip
    s = read_session(out)
    # the OAK-D's noise model is on by default, in the command and in SimulationSettings
    oak_d = StereoNoise.of_sensor(SensorModel.of(CAL.depth, "oak-d"))
    assert SHORT.stereo == oak_d
    assert s.records == simulate(Scene.load("corner"), CAL, SHORT)
    assert s.metadata["session"]["sensor"] == "oak-d"
    assert s.truth_surface_spec() == {"kind": "analytic", "name": "corner"}
    smooth = tmp_path / "smooth.mcap"
    assert main(["simulate-session", "--surface", "corner", "--seconds", "1", "--depth-fps",
                 "3", "--seed", "4", "--sensor", "smooth", "--out", str(smooth)]) == 0  # fmt: skip
    smooth_noise = replace(SHORT, stereo=StereoNoise.named("smooth"))
    assert read_session(smooth).records == simulate(Scene.load("corner"), CAL, smooth_noise)
    assert read_session(smooth).metadata["session"]["sensor"] == "smooth"


def test_a_noise_model_is_chosen_by_name() -> None:
    assert StereoNoise.named("smooth") == StereoNoise()
    kinect = StereoNoise.named("kinect")
    assert kinect.name == "kinect" and kinect.occlusion and kinect.flying > 0
    with pytest.raises(InputError, match="unknown depth sensor 'lidar'"):
        StereoNoise.named("lidar")


def test_cli_errors(tmp_path: Path) -> None:
    args = ["simulate-session", "--surface", "plane", "--out", str(tmp_path / "x.mcap")]
    assert main([*args, "--seconds", "0"]) == 2
    assert main([*args, "--depth-fps", "0"]) == 2
    assert main(["simulate-session", "--surface", "x.stl", "--out", str(tmp_path / "y")]) == 2


def test_imu_is_consistent_with_the_true_motion() -> None:
    settings = SimulationSettings(seconds=3.0, depth_fps=1.0, seed=7)
    recs = simulate(Scene.load("plane"), CAL, settings)
    imu = [r for r in recs if isinstance(r, ImuSample)]
    poses = {r.t_ns: r for r in recs if isinstance(r, TruthPose)}
    R = np.array([rotation_of(poses[s.sensor_ns].quaternion) for s in imu])
    p = np.array([poses[s.sensor_ns].position for s in imu])
    dt = 1.0 / settings.imu.rate_hz
    # angular rate from consecutive true attitudes, in P
    d = np.einsum("nji,njk->nik", R[:-1], R[1:])
    w_true = np.stack(
        [d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], -1
    )
    w_true /= 2 * dt
    gyro = np.array([s.gyro for s in imu]) @ CAL.R_P_I.T
    w_meas = (gyro[:-1] + gyro[1:]) / 2
    res = w_meas - w_true
    assert np.abs(np.median(res, axis=0)).max() < 0.02  # a small constant bias
    assert np.std(res, axis=0).max() < 0.01
    assert np.abs(w_true).max() > 0.03  # the device did turn
    # specific force from the true trajectory: R^T (a - g)
    a_w = (p[2:] - 2 * p[1:-1] + p[:-2]) / dt**2
    f_true = np.einsum("nji,nj->ni", R[1:-1], a_w - GRAVITY_W)
    accel = np.array([s.accel for s in imu])[1:-1] @ CAL.R_P_I.T
    res_a = accel - f_true
    assert np.abs(np.median(res_a, axis=0)).max() < 0.5
    assert np.std(res_a, axis=0).max() < 0.1
    assert np.linalg.norm(np.median(accel, axis=0)) == pytest.approx(9.80665, abs=0.5)


def test_hand_motion_has_still_phases() -> None:
    h = HandMotion(4.0, seed=1)
    t = np.linspace(0, 4, 400)
    assert h.moving(t).any() and (~h.moving(t)).any()
    R, _ = h.pose(np.array([0.0]))
    q = quaternion(R[0])
    assert np.allclose(rotation_of((q[0], q[1], q[2], q[3])), R[0])


def plane_points(z: float) -> np.ndarray:
    d = CAL.depth
    v, u = np.mgrid[0 : d.height, 0 : d.width].astype(float)
    rays = np.stack([(u - d.K[0, 2]) / d.K[0, 0], (v - d.K[1, 2]) / d.K[1, 1], np.ones_like(u)], -1)
    return rays * z


def test_stereo_error_grows_with_depth_squared() -> None:
    rng = np.random.default_rng(0)
    sd = []
    for z in (1.0, 3.0):
        depth = stereo_depth(plane_points(z), CAL.depth, StereoNoise(), rng).astype(float) / 1000
        ok = depth > 0
        sd.append(np.std(depth[ok] - z))
    assert 5 < sd[1] / sd[0] < 13  # ~ (3/1)^2
    q = StereoNoise(white_px=0, correlated_px=0, median=0)
    depth = stereo_depth(plane_points(1.5), CAL.depth, q, rng)
    fb = CAL.depth.focal * CAL.depth.baseline_m
    disparity = fb / (depth[depth > 0] / 1000.0)
    assert np.allclose(disparity * 8, np.round(disparity * 8), atol=0.05)  # 1/8 px steps


def test_invalid_pixels_at_edges_grazing_and_range() -> None:
    rng = np.random.default_rng(0)
    n = StereoNoise()
    frontal = stereo_depth(plane_points(1.5), CAL.depth, n, rng)
    assert not frontal[:, :10].any()  # the left band only one camera sees
    assert 0.9 < (frontal > 0).mean() < 0.99
    assert not stereo_depth(plane_points(0.2), CAL.depth, n, rng).any()  # too close
    scene = Scene.load("sphere-convex")
    d = CAL.depth
    pts = scene.points_seen(d.K, d.width, d.height, np.eye(3), np.zeros(3))
    depth = stereo_depth(pts, d, n, rng)
    rim = np.isfinite(pts[..., 2]) & (np.abs(pts[..., 0] - 0.05) > 0.55)  # grazing rim
    centre = np.isfinite(pts[..., 2]) & (np.abs(pts[..., 0] - 0.05) < 0.2)
    assert (depth[rim] > 0).mean() < 0.5 * (depth[centre] > 0).mean()


def test_depth_frames_follow_the_rate() -> None:
    recs = simulate(Scene.load("plane"), CAL, SimulationSettings(seconds=1.0, depth_fps=4.0))
    frames = [r for r in recs if isinstance(r, DepthFrame)]
    assert len(frames) == 4 and all(f.receive_ns > f.sensor_ns for f in frames)
    with pytest.raises(InputError):
        Scene.load("no-such-surface")


@pytest.mark.parametrize("name", ["sphere-convex", "wall-floor"])
def test_depths_at_a_few_pixels_are_those_of_the_whole_frame(name: str) -> None:
    """The shadow map's look-up at a few pixels (``depths_seen``) gives the depths the
    whole frame's cast gives there, NaN where nothing is hit (analytic and mesh), from a
    turned, moved camera. Same rays, same casts: the two differ only by the matrix
    product's rounding, so 1e-12 relative (a few ulps of ~1e-16 times the 3 terms)."""
    scene = Scene.load(name)
    d = CAL.depth
    R = Rotation.from_rotvec([0.05, -0.1, 0.02]).as_matrix()
    t = np.array([0.02, -0.03, 0.1])
    whole = scene.points_seen(d.K, d.width, d.height, R, t)[..., 2].ravel()
    pixels = np.random.default_rng(1).choice(whole.size, 500, replace=False)
    got = scene.depths_seen(d.K, d.width, d.height, R, t, pixels)
    assert np.isnan(whole[pixels]).any() == (name == "sphere-convex")
    np.testing.assert_allclose(got, whole[pixels], rtol=1e-12, equal_nan=True)
