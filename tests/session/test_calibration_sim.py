"""The calibration simulator's pieces and the new session records: camera frames and
patterns through the codec, shadows in the rendered captures, the scenes, the path,
the true rig in a session."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.mesh_surface import MeshSurface
from adaproj_edge.hal.camera import CameraFrame
from adaproj_edge.session import schemas
from adaproj_edge.session.calibration_sim import (
    STOPS,
    CalibrationSimSettings,
    SimUser,
    StopPath,
    sim_rig,
)
from adaproj_edge.session.codec import decode, encode, topic_of
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.records import PatternShown
from adaproj_edge.session.scene_render import CameraOptics, lit_view, render_capture
from adaproj_edge.session.simulator import (
    T0_NS,
    ImuNoise,
    Scene,
    SimulationSettings,
    scoring_projector,
    simulate_session,
    truth_rig,
)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(0, 2**62),
    st.integers(0, 2**62),
    st.integers(0, 2**31),
    st.integers(1, 20),
    st.integers(1, 20),
    st.integers(1, 33_000),
    st.integers(100, 1600),
    st.binary(min_size=400, max_size=400),
)
def test_camera_frames_round_trip(
    sensor: int, receive: int, seq: int, w: int, h: int, exposure: int, iso: int, raw: bytes
) -> None:
    image = np.frombuffer(raw[: w * h], np.uint8).reshape(h, w)
    f = CameraFrame(sensor, receive, seq, image, exposure, iso)
    assert topic_of(f) == schemas.CAMERA
    assert decode(schemas.CAMERA, encode(f), receive, seq) == f


@given(st.integers(0, 2**62), st.integers(0, 100), st.integers(0, 100), st.text(max_size=20))
def test_patterns_round_trip(t: int, pose: int, index: int, name: str) -> None:
    p = PatternShown(t, pose, index, name)
    assert topic_of(p) == schemas.PATTERN
    assert decode(schemas.PATTERN, encode(p), t, 0) == p


@settings(max_examples=200, deadline=None)
@given(st.sampled_from([schemas.CAMERA, schemas.PATTERN]), st.binary(max_size=200))
def test_malformed_messages_are_input_errors(topic: str, data: bytes) -> None:
    try:
        decode(topic, data, 0, 0)
    except InputError:
        pass


def test_shadows_and_light() -> None:
    """A small panel 0.5 m ahead of a wall 2 m away: where the projector's ray to a
    wall point the camera sees passes through the panel, the camera sees ambient
    light only (the camera, 4 cm off the projector, sees a strip of that shadow)."""
    v = np.array(
        [[-3, -3, 2.0], [3, -3, 2.0], [3, 3, 2.0], [-3, 3, 2.0],
         [-0.05, -0.05, 0.5], [0.05, -0.05, 0.5], [0.05, 0.05, 0.5], [-0.05, 0.05, 0.5]]
    )  # fmt: skip
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    scene = Scene(MeshSurface("wall-panel", v, f), {"kind": "mesh", "name": "wall-panel"})
    rig = Calibration.default()
    K = rig.depth.intrinsics_at(320, 200)
    optics = CameraOptics(albedo_texture=0.0, interreflection=0.0, read_noise=0.0, shot_noise=0.0)
    view = lit_view(scene, rig, np.eye(3), np.zeros(3), K, (320, 200), optics)
    rng = np.random.default_rng(0)
    white = render_capture(view, np.full((800, 1280, 3), 255, np.uint8), optics, 8000, 400, rng)
    off = render_capture(view, None, optics, 8000, 400, rng)
    # the truth: each camera pixel's ray (frame D, at the device pose = W)
    T = rig.T_P_D
    uu, vv = np.meshgrid(np.arange(320), np.arange(200))
    d = np.stack([(uu - K[0, 2]) / K[0, 0], (vv - K[1, 2]) / K[1, 1], np.ones(uu.shape)], -1)
    rays, centre = d @ T[:3, :3].T, T[:3, 3]

    def at(z: float) -> np.ndarray:  # where the camera rays cross the plane at depth z
        return centre[:2] + ((z - centre[2]) / rays[..., 2])[..., None] * rays[..., :2]

    near_panel = np.abs(at(0.5)).max(axis=-1)  # < 0.05: the camera sees the panel
    through = np.abs(at(2.0) * 0.25).max(axis=-1)  # the projector's ray at z = 0.5
    core = (through < 0.04) & (near_panel > 0.06)  # in the shadow, the wall in view
    lit = (through > 0.06) & (near_panel > 0.06) & np.all(np.abs(at(2.0)) < [0.6, 0.35], -1)
    assert core.sum() > 30 and lit.sum() > 1000
    assert np.abs(white[core].astype(int) - off[core]).max() <= 1
    assert white[lit].min() > off[lit].max() + 20


def test_wall_floor_scene() -> None:
    s = Scene.load("wall-floor")
    o = np.zeros((2, 3))
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.5, 1.0]])
    t = s.surface.intersect(o, d)
    assert t[0] == pytest.approx(2.0) and t[1] == pytest.approx(0.9)  # floor 0.45 m below
    assert s.spec["start"][3] < 0  # looking down at the start


def test_stop_path_rests_and_moves() -> None:
    path = StopPath(seconds=0.0, stops=STOPS[:2].copy())
    path.moves.append((1.0, STOPS[0], STOPS[1]))
    x = path.state(np.array([0.5, 1.0, 3.0]))
    assert (
        np.allclose(x[0], STOPS[0]) and np.allclose(x[1], STOPS[0]) and np.allclose(x[2], STOPS[1])
    )
    f, w = path.imu_truth(np.array([0.5, 3.0]))
    assert np.allclose(w, 0, atol=1e-9)
    assert np.linalg.norm(f[0]) == pytest.approx(9.80665, abs=1e-6)


def test_a_session_on_a_true_rig_records_the_nominal_one(tmp_path: Path) -> None:
    nominal = Calibration.default()
    K = nominal.projector.K.copy()
    K[1, 2] += 300
    truth = Calibration(
        type(nominal.projector)(K, 1280, 800), nominal.depth, nominal.T_P_D, nominal.R_P_I
    )
    out = tmp_path / "s.mcap"
    simulate_session(Scene.load("plane"), out, nominal, SimulationSettings(seconds=0.4), truth)
    s = read_session(out)
    assert np.array_equal(s.calibration.projector.K, nominal.projector.K)
    rig = truth_rig(s.attachments)
    assert rig is not None and np.array_equal(rig.projector.K, K)
    assert scoring_projector(s.attachments, nominal.projector).K[1, 2] == K[1, 2]
    assert scoring_projector({}, nominal.projector) is nominal.projector


def test_imu_samples_made_ahead_show_a_move_told_after_they_were_made() -> None:
    """The simulated IMU makes its samples ahead of the clock and hands each out when
    it is due; a move the user hears afterwards (it starts ``REACTION_S`` later) still
    shows in them: every sample agrees with the truth of the whole path, computed once
    the path is complete. Without noise or biases the only difference is the chip's
    quantisation: half a step of each sensor, and rounding."""
    quiet = ImuNoise(0.0, 0.0, 0.0, 0.0)
    sim = sim_rig(
        Scene.load("corner"), Calibration.default(), CalibrationSimSettings(imu_noise=quiet)
    )
    w, clock = sim.world, sim.world.clock
    user = SimUser(w, lambda rec: None)
    got = []
    for step in range(1750):  # 3.5 s, polled every 2 ms as the procedure does
        if step in (275, 1030):  # told to move at 0.55 s and 2.06 s
            user.say("move", "")
        while (s := sim.imu.read()) is not None:
            assert s.receive_ns <= clock.now_ns()
            got.append(s)
        clock.sleep_until(clock.now_ns() + 2_000_000)
    t = np.array([s.sensor_ns for s in got])
    assert np.all(np.diff(t) == sim.imu.dt_ns) and t[-1] > T0_NS + 3.4e9
    f_p, w_p = w.path.imu_truth((t - T0_NS) * 1e-9)
    R_I_P = w.rig.R_P_I.T
    acc, gyr = np.array([s.accel for s in got]), np.array([s.gyro for s in got])
    assert np.abs(gyr).max() > 0.1  # the moves show
    imu = w.settings.imu
    assert np.abs(acc - f_p @ R_I_P.T).max() <= imu.accel_scale / 2 + 1e-9
    assert np.abs(gyr - w_p @ R_I_P.T).max() <= imu.gyro_scale / 2 + 1e-9


def test_the_light_on_a_turned_wall_is_lambert_s() -> None:
    """A wall turned 30 degrees, 2 m ahead, albedo 1: each camera point lit by projector
    pixel (u, v) gets cos(incidence) x (1.5 m / distance)^2, the point computed here
    from (u, v) and the wall's equation. ``uv`` and ``light`` are float32 (relative
    rounding 6e-8, the point's ~1e-7 over the wall's ~1000 px), so 1e-5 is far above."""
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    v = np.array([[x * c, y, 2.0 + x * s] for x, y in ((-3, -2), (3, -2), (3, 2), (-3, 2))])
    scene = Scene(MeshSurface("wall", v, np.array([[0, 1, 2], [0, 2, 3]])), {"kind": "mesh"})
    rig = Calibration.default()
    optics = CameraOptics(albedo_texture=0.0, supersample=2)
    view = lit_view(scene, rig, np.eye(3), np.zeros(3), rig.depth.intrinsics_at(160, 100),
                    (160, 100), optics)  # fmt: skip
    lit = view.uv[..., 0] > -5
    assert lit.mean() > 0.15  # the projector lights a quarter of the camera's view
    uv = view.uv[lit].astype(np.float64)
    rays = np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(rig.projector.K).T
    n = np.array([s, 0.0, -c])
    points = rays * ((n @ [0.0, 0.0, 2.0]) / (rays @ n))[:, None]
    dist = np.linalg.norm(points, axis=1)
    truth = np.abs(points @ n) / dist * (optics.reference_m / dist) ** 2
    assert np.abs(view.light[lit] / truth - 1).max() < 1e-5
