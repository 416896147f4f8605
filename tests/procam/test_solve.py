"""The projector solve on point pairs made from a known projector (noise, outliers,
lens distortion), the truth computed here with OpenCV's own projection."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from adaproj_edge.errors import CalibrationError
from adaproj_edge.procam.pairs import Pairs
from adaproj_edge.procam.solve import ProjectorModel, SolveSettings, dlt, solve_projector

SIZE = (1280, 800)


def true_rig(
    dist: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    K = np.array([[1845.8, 0.0, 654.5], [0.0, 1845.8, 699.5], [0.0, 0.0, 1.0]])
    rvec = Rotation.from_euler("xyz", [1.2, -1.4, 0.5], degrees=True).as_rotvec()
    tvec = np.array([0.024, -0.031, 0.012])
    return K, rvec, tvec, np.zeros(5) if dist is None else dist


def nominal() -> ProjectorModel:
    K = np.array([[1792.0, 0.0, 639.5], [0.0, 1792.0, 399.5], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, 3] = [0.012, -0.04, 0.005]
    return ProjectorModel(K, np.zeros(5), T)


def make_pairs(
    rig: tuple[np.ndarray, ...],
    n: int = 4000,
    noise: float = 0.2,
    outliers: float = 0.0,
    seed: int = 0,
) -> Pairs:
    """Points of a corner-like scene over several poses (frame D), projected by the
    rig with OpenCV, with pixel noise and a share of gross errors."""
    K, rvec, tvec, dist = rig
    rng = np.random.default_rng(seed)
    R = Rotation.from_rotvec(rvec).as_matrix()
    uv_target = rng.uniform([0, 0], SIZE, size=(n, 2))
    z = rng.uniform(1.0, 2.3, size=n)  # depth along the projector axis
    rays = np.c_[(uv_target - K[:2, 2]) / K[0, 0], np.ones(n)]
    pts_p = rays * z[:, None]
    pts_d = (pts_p - tvec) @ R  # into D
    uv, _ = cv2.projectPoints(pts_d, rvec, tvec, K, dist)
    uv = uv.reshape(-1, 2) + rng.normal(scale=noise, size=(n, 2))
    bad = rng.random(n) < outliers
    uv[bad] += rng.uniform(-60, 60, size=(int(bad.sum()), 2))
    sig = np.full(n, noise)
    return Pairs(np.zeros((n, 2)), pts_d, uv, sig, np.zeros(n), np.arange(n) % 5)


def test_recovers_the_rig_from_a_far_guess_with_outliers() -> None:
    rig = true_rig()
    sol = solve_projector(make_pairs(rig, outliers=0.05), nominal(), SIZE)
    K, rvec, tvec, _ = rig
    m = sol.model
    assert m.K[0, 0] / K[0, 0] - 1 == pytest.approx(0, abs=2e-4)
    assert m.K[1, 1] / K[1, 1] - 1 == pytest.approx(0, abs=2e-4)
    assert np.hypot(*(m.K[:2, 2] - K[:2, 2])) < 0.5
    dR = Rotation.from_matrix(m.T_P_D[:3, :3]) * Rotation.from_rotvec(rvec).inv()
    assert dR.magnitude() < np.radians(0.02)
    assert np.linalg.norm(m.T_P_D[:3, 3] - tvec) < 0.5e-3
    assert not sol.distortion_used
    # the gross errors are the outliers, and nothing else much
    assert 0.93 < sol.inliers.mean() < 0.96
    assert sol.rms_px == pytest.approx(0.2 * np.sqrt(2), rel=0.15)
    assert sol.sigma["cx"] < 0.5 and sol.sigma["fx"] < 1e-3


def test_lens_distortion_is_kept_when_it_pays() -> None:
    dist = np.array([0.08, -0.1, 0.0, 0.0, 0.0])
    rig = true_rig(dist)
    pairs = make_pairs(rig, n=6000, noise=0.1)
    sol = solve_projector(pairs, nominal(), SIZE)
    assert sol.distortion_used
    assert sol.model.distortion[0] == pytest.approx(0.08, abs=0.01)
    # the model reprojects like OpenCV's with the true distortion
    K, rvec, tvec, _ = rig
    uv, _ = cv2.projectPoints(pairs.points[:50], rvec, tvec, K, dist)
    assert np.abs(sol.model.project(pairs.points[:50]) - uv.reshape(-1, 2)).max() < 0.3
    none = solve_projector(pairs, nominal(), SIZE, SolveSettings(distortion="none"))
    assert not none.distortion_used and none.rms_px > 2 * sol.rms_px


def test_dlt_alone() -> None:
    rig = true_rig()
    m = dlt(*(lambda p: (p.points, p.projector_uv))(make_pairs(rig, noise=0.0)))
    assert np.allclose(m.K, rig[0], atol=1e-3)


def test_too_few_pairs() -> None:
    pairs = make_pairs(true_rig(), n=30)
    with pytest.raises(CalibrationError, match="only 30 point pairs"):
        solve_projector(pairs, nominal(), SIZE)


def test_pairs_that_fit_no_projector() -> None:
    pairs = make_pairs(true_rig(), n=500)
    rng = np.random.default_rng(1)
    scrambled = Pairs(
        pairs.camera_uv, pairs.points, rng.uniform(0, 1280, (500, 2)), pairs.sigma_uv,
        pairs.sigma_z, pairs.pose,
    )  # fmt: skip
    sol = solve_projector(scrambled, nominal(), SIZE)
    assert sol.rms_px > 50 or sol.inliers.mean() < 0.5
