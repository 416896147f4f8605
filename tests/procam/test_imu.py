"""R_P_I from plane normals and the integrated gyro, on motions made here with scipy's
rotations (the truth), and plane normals from a synthetic depth image."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from adaproj_edge.procam.imu import PoseMotion, integrate_gyro, scene_planes, solve_imu_rotation

RATE = 208.0


def gyro_track(
    turns: list[Rotation], bias: np.ndarray, hold_s: float = 2.0, move_s: float = 1.5
) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]], list[Rotation]]:
    """Body rates (in P) of a device turning through ``turns`` (orientations R_W_P),
    holding each for ``hold_s``: sample times (ns), gyro (rad/s) and each hold's span."""
    t_all, w_all, spans = [], [], []
    t = 0.0
    dt = 1 / RATE
    for k, R in enumerate(turns):
        spans.append((int(t * 1e9), int((t + hold_s) * 1e9)))
        n = int(hold_s * RATE)
        t_all += [t + i * dt for i in range(n)]
        w_all += [np.zeros(3)] * n
        t += n * dt
        if k + 1 < len(turns):
            slerp = Slerp([0.0, 1.0], Rotation.concatenate([R, turns[k + 1]]))
            m = int(move_s * RATE)
            s = np.linspace(0, 1, m + 1)
            s = s * s * (3 - 2 * s)
            Rs = slerp(s)
            for i in range(m):
                d = (Rs[i].inv() * Rs[i + 1]).as_rotvec()  # body-frame step
                t_all.append(t + (i + 1) * dt)
                w_all.append(d / dt)
            t += m * dt
    return np.array(t_all) * 1e9, np.array(w_all) + bias, spans, turns


def test_integrate_gyro_of_a_constant_turn() -> None:
    t = np.arange(1, 209) / RATE * 1e9
    w = np.tile([0.0, 0.3, 0.1], (208, 1))
    R = integrate_gyro(t, w + 0.01, 0, int(t[-1]), np.full(3, 0.01), np.full(3, 0.01))
    assert np.allclose(R, Rotation.from_rotvec([0.0, 0.3, 0.1]).as_matrix(), atol=1e-9)


def _case(
    two_axes: bool = True,
) -> tuple[list[PoseMotion], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    R_P_I = Rotation.from_euler("xyz", [3.0, -2.5, 2.0], degrees=True).as_matrix()
    R_P_D = Rotation.from_euler("xyz", [0.5, 1.5, -0.3], degrees=True).as_matrix()
    eul = [(0, 0, 0), (5, -14, 2), (-8, 12, -3), (10, 6, 4)] if two_axes else [
        (0, 0, 0), (0, -14, 0), (0, 12, 0), (0, 6, 0)]  # fmt: skip
    turns = [Rotation.from_euler("xyz", e, degrees=True) for e in eul]
    bias_i = np.array([0.004, -0.006, 0.002])
    t, w_p, spans, _ = gyro_track(turns, np.zeros(3))
    gyro_i = w_p @ R_P_I + bias_i  # rates in I: R_I_P w_p
    walls = np.array([[0.707, 0.0, -0.707], [-0.707, 0.0, -0.707], [0.0, -1.0, 0.0]])
    poses = []
    for R_W_P, (t0, t1) in zip(turns, spans, strict=True):
        n_p = walls @ R_W_P.as_matrix()  # R_P_W n_W
        poses.append(PoseMotion(n_p @ R_P_D, bias_i, R_P_I.T @ [0, -9.81, 0], t0, t1))
    return poses, t, gyro_i, R_P_D, R_P_I


def test_recovers_R_P_I_from_a_nominal_5_degrees_off() -> None:
    poses, t, gyro, R_P_D, R_P_I = _case()
    sol = solve_imu_rotation(poses, t, gyro, R_P_D, np.eye(3))
    err = Rotation.from_matrix(sol.R_P_I @ R_P_I.T).magnitude()
    assert sol.measured and np.degrees(err) < 0.02
    assert sol.matches >= 6 and sol.max_turn_deg > 20
    assert np.allclose(sol.up, [0, -1, 0], atol=1e-3)  # up is -y in P at the first pose


def test_one_turn_axis_leaves_R_P_I_unmeasured() -> None:
    poses, t, gyro, R_P_D, _ = _case(two_axes=False)
    sol = solve_imu_rotation(poses, t, gyro, R_P_D, np.eye(3))
    assert not sol.measured and "two different axes" in sol.problem
    assert np.array_equal(sol.R_P_I, np.eye(3))


def test_one_pose_leaves_R_P_I_unmeasured() -> None:
    poses, t, gyro, R_P_D, _ = _case()
    assert not solve_imu_rotation(poses[:1], t, gyro, R_P_D, np.eye(3)).measured


def test_scene_planes_of_a_corner_depth_image() -> None:
    """Two walls meeting in a vertical crease, seen by a 320x200 camera."""
    K = np.array([[220.0, 0, 159.5], [0, 220.0, 99.5], [0, 0, 1]])
    v, u = np.mgrid[0:200, 0:320].astype(float)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    normals = np.array([[0.6, 0.1, -0.8], [-0.7, 0.05, -0.71]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = np.array([-1.5, -1.4])
    z = np.min([offsets[i] / (rays @ normals[i]) for i in range(2)], axis=0) * 1.0
    z = np.where(z > 0, z, np.nan)
    z += np.random.default_rng(0).normal(scale=0.002, size=z.shape)
    found = scene_planes(z, K, block=4)
    assert len(found) == 2
    for n in normals:
        best = max(abs(float(f @ n)) for f in found)
        assert np.degrees(np.arccos(min(best, 1.0))) < 0.05


@pytest.mark.parametrize("block", [4, 8])
def test_no_planes_in_an_empty_depth_image(block: int) -> None:
    K = np.array([[220.0, 0, 159.5], [0, 220.0, 99.5], [0, 0, 1]])
    assert scene_planes(np.full((200, 320), np.nan), K, block).shape == (0, 3)
