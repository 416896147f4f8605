"""Up is decided by one rule: gravity on a wall, away from the device on a floor or a
table, the wall's rule where the content's centre is on the wall of a wall and a floor.

Each scene is built in a world frame (X right, Y up, Z ahead of the device's heading)
with the device turned by heading, pitch and roll; the expected "up" is computed there
(gravity on the wall's plane; the device's heading, level, on a floor) and compared
with the way the warp's content points up on the surface at the content's centre
(the content's -y carried to the surface by an affine fit of the warp's vertices)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp

SIZE = (640, 400)
P = Projector.default()
WORLD_UP = np.array([0.0, 1.0, 0.0])
F = NDArray[np.float64]


def _rot(axis: int, a: float) -> F:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _device(heading_deg: float, pitch_deg: float, roll_deg: float) -> F:
    """Frame P's axes in the world (columns): level and looking along +Z, then rolled
    about its optical axis, pitched down and turned to the heading."""
    level = np.diag([1.0, -1.0, 1.0])  # x right, y down, z ahead
    return (
        _rot(1, np.deg2rad(heading_deg))
        @ _rot(0, np.deg2rad(pitch_deg))
        @ level
        @ _rot(2, np.deg2rad(roll_deg))
    )


def _scene(R: F, planes: list[tuple[F, float]]) -> Surface:
    """The surface the projector at the world's origin, turned by ``R``, sees of the
    room bounded by ``planes`` (normal n into the room, n . X = c; the first one each
    ray leaves the room through), on an 80x50 lattice."""
    xs = np.linspace(0, P.width - 1, 80)
    ys = np.linspace(0, P.height - 1, 50)
    rays = P.rays(np.stack(np.meshgrid(xs, ys), axis=-1))
    d_world = rays @ R.T
    t = np.full(rays.shape[:2], np.inf)
    for n, c in planes:
        den = d_world @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            tt = c / den
        t = np.where((den < 0) & (tt > 0) & (tt < t), tt, t)
    pts = np.where(np.isfinite(t)[..., None], rays * t[..., None], np.nan)
    return Surface(pts.astype(np.float32), P)


def _floor(height: float) -> tuple[F, float]:
    return WORLD_UP, -height  # Y = -height; the room is above it


def _shown_up(surface: Surface, gravity_up: F) -> tuple[F, F]:
    """The content's up on the surface at its centre (unit, frame P), and the surface's
    normal there, from the warp made with gravity ``gravity_up`` (frame P)."""
    warp = compute_warp(surface, SIZE, None, WarpSettings(up=tuple(gravity_up)))
    xy = warp.image_xy.reshape(-1, 2)
    pts = P.rays(warp.grid_uv.reshape(-1, 2)) * warp.depth.reshape(-1, 1)
    centre = np.array([SIZE[0] / 2, SIZE[1] / 2])
    near = np.isfinite(xy).all(axis=1) & (np.linalg.norm(xy - centre, axis=1) < 0.12 * SIZE[0])
    assert near.sum() >= 6
    a = np.column_stack([xy[near] - centre, np.ones(int(near.sum()))])
    coef = np.linalg.lstsq(a, pts[near], rcond=None)[0]  # (3, 3): d/dx, d/dy, centre
    up = -coef[1] / np.linalg.norm(coef[1])
    normal = np.cross(coef[0], coef[1])
    return up, normal / np.linalg.norm(normal)


def _angle_deg(a: F, b: F) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(b), -1.0, 1.0))))


def _expect_wall(R: F, up: F, normal: F) -> float:
    g = R.T @ WORLD_UP
    return _angle_deg(up, g - (g @ normal) * normal)


def _expect_away(R: F, up: F, heading_deg: float) -> float:
    h = np.deg2rad(heading_deg)
    away = R.T @ np.array([np.sin(h), 0.0, np.cos(h)])  # level, along the heading
    return _angle_deg(up, away)


@pytest.mark.parametrize(
    ("heading", "pitch", "roll"),
    [(0, 40, 0), (30, 40, -25), (-60, 60, 15), (120, 75, 25), (200, 60, 0), (0, 90, 0)],
)
def test_on_a_level_floor_up_points_away_from_the_device(
    heading: float, pitch: float, roll: float
) -> None:
    """The content's up runs along the device's heading on the floor (it was upside
    down or turned: gravity has no direction on a level floor)."""
    R = _device(heading, pitch, roll)
    up, _ = _shown_up(_scene(R, [_floor(1.2)]), R.T @ WORLD_UP)
    assert _expect_away(R, up, heading) < 5.0


def test_on_a_drafting_table_up_points_away_up_its_slope() -> None:
    """A table tilted 30 deg toward the device (within 45 deg of level): away from the
    device, along the device's forward projected onto the table."""
    R = _device(10, 55, 10)
    tilt = np.deg2rad(30)
    heading = np.deg2rad(10)
    # the table's normal: up, tipped back toward the device (along -heading)
    n = np.cos(tilt) * WORLD_UP - np.sin(tilt) * np.array([np.sin(heading), 0, np.cos(heading)])
    up, normal = _shown_up(_scene(R, [(n, -0.8)]), R.T @ WORLD_UP)
    forward = np.array([0.0, 0.0, 1.0])
    want = forward - (forward @ normal) * normal
    assert _angle_deg(up, want) < 5.0
    assert up @ (R.T @ WORLD_UP) > 0  # away up the slope, not down it


@pytest.mark.parametrize(("heading", "roll"), [(0, 0), (25, -15), (-20, 20)])
def test_on_a_wall_up_is_gravity(heading: float, roll: float) -> None:
    R = _device(heading, 5, roll)
    wall = (np.array([0.0, 0.0, -1.0]), -2.0)  # Z = 2 m ahead
    up, normal = _shown_up(_scene(R, [wall]), R.T @ WORLD_UP)
    assert _expect_wall(R, up, normal) < 2.0


@pytest.mark.parametrize(("pitch", "on"), [(25, "wall"), (37, "floor")])
@pytest.mark.parametrize(("heading", "roll"), [(0, 0), (20, 10)])
def test_across_a_wall_and_a_floor_the_part_under_the_centre_decides(
    heading: float, roll: float, pitch: float, on: str
) -> None:
    """The wall meets the floor 31 deg below the device's heading: looking 25 deg
    down the content's centre is on the wall (gravity), 37 deg down on the floor
    (away). Upright either way (it was turned 90 deg)."""
    R = _device(heading, pitch, roll)
    h = np.deg2rad(heading)
    wall = (-np.array([np.sin(h), 0.0, np.cos(h)]), -2.0)  # 2 m ahead, facing the device
    up, normal = _shown_up(_scene(R, [_floor(1.2), wall]), R.T @ WORLD_UP)
    if on == "wall":
        assert abs(normal @ (R.T @ WORLD_UP)) < 0.2  # the centre is on the wall
        assert _expect_wall(R, up, normal) < 2.0
    else:
        assert abs(normal @ (R.T @ WORLD_UP)) > 0.9  # on the floor
        assert _expect_away(R, up, heading) < 5.0


@pytest.mark.parametrize("lean", [(3.0, 0.0), (-3.0, 0.0), (0.0, 3.0)])
def test_gravity_a_few_degrees_off_does_not_turn_a_floor(lean: tuple[float, float]) -> None:
    """Gravity's estimate 3 deg off (an IMU's error, a floor not quite level): "down"
    then has a direction on the floor - the way it leans - which used to decide (the
    poster upside down when it leant toward the far side)."""
    R = _device(15, 55, 5)
    tilt = _rot(0, np.deg2rad(lean[0])) @ _rot(2, np.deg2rad(lean[1]))
    gravity = R.T @ (_rot(1, np.deg2rad(15)) @ tilt @ WORLD_UP)
    up, _ = _shown_up(_scene(R, [_floor(1.2)]), gravity)
    assert _expect_away(R, up, 15) < 5.0
