"""The rotation homography against projected points, and the frame it draws."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.rotations import rotation_matrix
from adaproj_edge.render.reproject import (
    inner_corners,
    map_points,
    margin_usage,
    reproject,
    rotation_between,
    rotation_homography,
)

PROJ = Projector.default()


def test_the_homography_maps_a_pixel_to_the_one_showing_the_same_ray() -> None:
    rng = np.random.default_rng(3)
    X = rng.uniform([-0.6, -0.4, 1.0], [0.6, 0.4, 3.0], size=(50, 3))  # points in world W
    R_old = rotation_matrix(np.array([0.01, -0.02, 0.005]))
    R_new = R_old @ rotation_matrix(np.array([-0.004, 0.006, 0.01]))
    u_old = PROJ.project(X @ R_old)  # pixels in the frame rendered at R_old
    u_new = PROJ.project(X @ R_new)  # where the same points are seen after turning
    H = rotation_homography(PROJ.K, R_old.T @ R_new)
    assert np.allclose(map_points(H, u_new), u_old, atol=1e-6)


def test_reproject_moves_a_dot_where_the_homography_says() -> None:
    frame = np.zeros((PROJ.height, PROJ.width, 4), np.uint8)
    frame[400:404, 640:644] = 255
    C = rotation_matrix(np.array([0.0, 0.003, 0.0]))
    H = rotation_homography(PROJ.K, C)
    for interpolation in ("linear", "nearest"):
        out = reproject(frame, H, interpolation=interpolation)  # type: ignore[arg-type]
        ys, xs = np.nonzero(out[..., 0] > 127)
        centre = map_points(np.linalg.inv(H), np.array([641.5, 401.5]))
        assert abs(xs.mean() - centre[0]) < 0.8 and abs(ys.mean() - centre[1]) < 0.8
    same = reproject(frame, np.eye(3), out=np.empty_like(frame))
    assert np.array_equal(same, frame)


def test_margin_usage_is_zero_still_and_one_at_the_edge() -> None:
    size = (PROJ.width, PROJ.height)
    assert margin_usage(PROJ.K, np.eye(3), size, 0.04) < 1e-9
    # a yaw that moves the centre by the whole horizontal margin (51.2 px) moves the
    # corners further: f (1 + x^2 / f^2) per radian
    yaw = np.arctan(0.04 * PROJ.width / PROJ.K[0, 0])
    used = margin_usage(PROJ.K, rotation_matrix(np.array([0.0, yaw, 0.0])), size, 0.04)
    x = 0.46 * PROJ.width
    assert used == pytest.approx(1 + (x / PROJ.K[0, 0]) ** 2, rel=0.02)
    assert margin_usage(PROJ.K, rotation_matrix(np.array([0.0, 0.01, 0.0])), size, 0.0) == np.inf
    c = inner_corners(size, 0.04)
    assert np.allclose(c[0], [0.04 * 1280 - 0.5, 0.04 * 800 - 0.5])


def test_rotation_between_recovers_a_rotation_of_pixels() -> None:
    rng = np.random.default_rng(4)
    u = rng.uniform([0, 0], [PROJ.width, PROJ.height], size=(20, 2))
    M = rotation_matrix(np.array([0.002, -0.004, 0.01]))
    moved = map_points(PROJ.K @ M @ np.linalg.inv(PROJ.K), u)
    got = rotation_between(PROJ.K, u, moved)
    assert np.allclose(got, M, atol=1e-9)
    u[3] = np.nan
    assert np.allclose(rotation_between(PROJ.K, u, moved), M, atol=1e-9)
    assert np.array_equal(rotation_between(PROJ.K, u[:2], moved[:2]), np.eye(3))
