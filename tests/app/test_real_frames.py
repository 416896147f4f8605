"""Real depth frames through the device path: every region a projector is aimed at gets
a picture, upright, undistorted on planes, off depth jumps, and ``adaproj warp`` agrees.

The frames (``tests/fixtures/real/``) were recorded by others with real structured-light
sensors; ``tests/realframes.py`` runs them through the runtime itself and computes the
figures from the raw points alone. The aims are the ones the device is held to on real
sensors; a case the device does not meet yet is marked ``xfail`` (strict) with today's
figure, and the mark goes when the device meets it.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pytest

from adaproj_edge.geometry.calibration import Calibration
from tests.realframes import (
    Figures,
    RealFrame,
    Region,
    figures,
    gravity_up,
    jacobians,
    jump_figures,
    load_frames,
    plane_hits,
    plane_tol,
    real_samples,
    upright_error,
)

MIN_VALID_PCT = 30.0  # a region with this much valid depth must get a picture
UPRIGHT_DEG = {"wall": 2.0, "floor": 5.0}
MAX_ANGLE = 0.02
MAX_SIZE = 0.02
MAX_JUMP_PCT = 1.0

pytestmark = pytest.mark.slow

FRAMES = load_frames()
CASES = [(f, r) for f in FRAMES for r in f.regions]


def _id(frame: RealFrame, region: Region) -> str:
    return f"{frame.name}/{region.name}"


# Today's misses, with today's figure (`tools/bench_real.py --no-render`): every region
# gets a picture, without a WarpError, and `adaproj warp` agrees; what is left is the
# upright on walls the device reconstructs with shear and on a cluttered wardrobe,
# distortion on a wall seen grazing, content on a hole in the depth. (A jump is counted
# beyond the frame's own disparity noise: at 4-5 m a fixed 5 cm counted one wall's noise.)
# The planes are snapped (the sensor's steps and slow error allowed for) and
# the warp holds them undistorted, putting what the rest of the footprint forces on the
# rest (a region's plane alone, exact, reads 0.000). On the corridor's wall the device
# snaps two planes where the harness fits one. Seen grazing, the plane fit's own
# spread (two robust fits to halves of one box's raw points differ by 0.5-3 deg) reads
# 0.04-0.16 of angle: the measurable line is the angle within 0.02 of it.
XFAIL: dict[str, dict[str, str]] = {
    "test_upright": {
        # the picture is on a 0.4 x 0.5 m patch of clutter at 3.6-3.8 m: planes fitted to
        # halves of its raw points read 6-31 deg (tools/bench_real.py's up_spr: 19 deg)
        "nyu_basement/wardrobe": "11.8 deg on a wall",
    },
    "test_planar_distortion": {
        # not one plane: the corridor's wall steps in by 12.5 cm at depth pixel u ~ 100-125
        # (a face at 2.29-2.35 m over all its rows between two parallel wall planes, their
        # normals 1 deg apart): the device's two planes there (offsets 0.77 and 0.59 m)
        # need a joint curvature of 77 px against the sensor's 4.5, so stay two
        # (tools/measure_sensor_bend.py reads the box's halves at 24 px, one-plane boxes
        # at 1.3-4.3)
        "sun3d_corridor/wall": "angle 0.279, size 0.012",
    },
    "test_planar_distortion_as_measured": {
        "sun3d_corridor/wall": "angle 0.279 against 0.02 + spread 0.164",
    },
    "test_off_depth_jumps": {
        # a 0.3 x 0.45 m hole in the Kinect's depth at 3.6 m, inside a surface its ring
        # fits within the sensor's error: filled, and the content is shown on it
        "nyu_basement/wardrobe": "0.1 % bridging, 6.4 % on nothing",
    },
}


def cases(test: str, planar_only: bool = False) -> list[object]:
    out: list[object] = []
    for frame, region in CASES:
        if planar_only and not region.planar:
            continue
        key = _id(frame, region)
        reason = XFAIL.get(test, {}).get(key)
        marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
        out.append(pytest.param(key, marks=marks, id=key))
    return out


@pytest.fixture(scope="module")
def results() -> dict[str, Figures]:
    """Every region's figures, computed once for the module."""
    return {_id(f, r): figures(f, r, render=False)[0] for f, r in CASES}


def test_the_frames_are_real_millimetre_depth_with_intrinsics() -> None:
    assert len(FRAMES) >= 3
    kinds = {r.kind for _, r in CASES}
    assert {"wall", "floor", "corner", "wall-objects", "desk"} <= kinds
    for f in FRAMES:
        assert f.depth_mm.dtype == np.uint16
        valid = f.depth_mm[f.depth_mm > 0]
        assert 300 < np.median(valid) < 10000  # millimetres of a room
        assert f.K[0, 0] > 0 and f.K[1, 1] > 0
        assert f.meta["source"]["licence"]


@pytest.mark.parametrize("case", cases("test_projected"))
def test_projected(case: str, results: dict[str, Figures]) -> None:
    fig = results[case]
    if fig.valid_pct < MIN_VALID_PCT:
        pytest.skip(f"{fig.valid_pct:.0f} % valid depth")
    assert fig.projected, fig.error


@pytest.mark.parametrize("case", cases("test_no_warp_error"))
def test_no_warp_error(case: str, results: dict[str, Figures]) -> None:
    fig = results[case]
    assert not fig.warp_failed, fig.error


@pytest.mark.parametrize("case", cases("test_upright"))
def test_upright(case: str, results: dict[str, Figures]) -> None:
    fig = results[case]
    assert fig.projected, fig.error
    assert not math.isnan(fig.upright_deg), "no content shown on a plane"
    assert fig.upright_deg < 90.0  # never upside down
    assert fig.upright_deg <= UPRIGHT_DEG[fig.upright_rule], fig.upright_rule


@pytest.mark.parametrize("case", cases("test_planar_distortion", planar_only=True))
def test_planar_distortion(case: str, results: dict[str, Figures]) -> None:
    fig = results[case]
    assert fig.projected, fig.error
    assert fig.plane_triangles > 100
    assert fig.angle <= MAX_ANGLE
    assert fig.size <= MAX_SIZE


@pytest.mark.parametrize("case", cases("test_planar_distortion_as_measured", planar_only=True))
def test_planar_distortion_as_measured(case: str, results: dict[str, Figures]) -> None:
    """The planar line the measure can verify: the angle figure within 0.02 of what it
    reads between two fits of the region's own raw points (its spread), the size
    within 0.02."""
    fig = results[case]
    assert fig.projected, fig.error
    assert fig.plane_triangles > 100
    assert 0.0 <= fig.spread < 0.5
    assert fig.angle <= MAX_ANGLE + fig.spread, fig.spread
    assert fig.size <= MAX_SIZE


@pytest.mark.parametrize("case", cases("test_off_depth_jumps"))
def test_off_depth_jumps(case: str, results: dict[str, Figures]) -> None:
    fig = results[case]
    assert fig.projected, fig.error
    assert fig.jump_pct <= MAX_JUMP_PCT, (fig.bridging_pct, fig.no_object_pct)


@pytest.mark.parametrize("case", cases("test_adaproj_warp_agrees"))
def test_adaproj_warp_agrees(case: str, results: dict[str, Figures]) -> None:
    fig = results[case]
    assert fig.projected == bool(fig.warp_ok), (fig.error, fig.warp_error)
    assert fig.projected  # both warp it


def test_the_figures_read_zero_on_clean_depth_of_the_same_rooms() -> None:
    """The measure itself: the TUM frame's camera and gravity, its depth replaced by a
    clean render of a wall 2.5 m ahead above its floor 1.3 m below (millimetres, as a
    sensor gives them): the device path's picture reads upright and undistorted, off
    any jump. (Floors are left to the real frames: their "up" rule is the device's.)"""
    frame = next(f for f in FRAMES if f.name == "tum_desk")
    up = gravity_up(frame)
    ahead = np.array([0.0, 0.0, 1.0]) - up[2] * up
    ahead /= np.linalg.norm(ahead)
    z = np.where(np.arange(frame.height)[:, None] < 360, plane_depth(frame, ahead, 2.5), 0.0)
    z = np.where(z > 0, z, plane_depth(frame, -up, 1.3))
    clean = replace(frame, depth_mm=np.rint(z * 1e3).astype(np.uint16))
    fig, _ = figures(clean, Region("wall", "wall", (320, 200), (100, 100, 540, 340)), render=False)
    assert fig.projected and fig.warp_ok
    assert fig.upright_rule == "wall" and fig.upright_deg < 0.1
    assert fig.angle < 0.002 and fig.size < 0.002
    assert fig.jump_pct == 0.0


def plane_depth(frame: RealFrame, n: np.ndarray, d: float) -> np.ndarray:
    """Depth (h, w) in metres of the plane ``n . X = d`` seen by ``frame``'s camera (0
    where it is not in front)."""
    v, u = np.mgrid[0 : frame.height, 0 : frame.width].astype(np.float64)
    K = frame.K
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    with np.errstate(divide="ignore"):
        z = d / (rays @ n)
    return np.where((z > 0.3) & (z < 8.0), z, 0.0)


def test_the_jump_figure_sees_silhouettes_not_slanted_walls() -> None:
    """The measure itself, on sampled real points: a wall at 61-79 deg incidence is no jump,
    nor a quantisation staircase on it; a box 0.5 m in front of a wall is, on the
    samples either side of its silhouette only; a shown sample far from any point is on
    nothing."""
    rows, cols = 60, 80
    f = 2000.0 / 8  # samples 8 px apart on a 2000 px focal length: 61-79 deg incidence
    v, u = np.mgrid[0:rows, 0:cols].astype(np.float64)
    rays = np.stack([(u - cols / 2) / f, (v - rows / 2) / f, np.ones_like(u)], -1)
    n = np.array([np.sin(np.radians(70.0)), 0.0, -np.cos(np.radians(70.0))])
    t = -1.0 / (rays @ n)  # the plane n . X = -1 (2.9 m ahead on the axis)
    z = np.round(t * 40) / 40  # 25 mm depth steps
    slanted = rays * z[..., None]
    shown = np.ones((rows, cols), bool)
    assert jump_figures(shown, slanted) == (0.0, 0.0)
    wall = rays * 3.0
    wall[:, 40:] = rays[:, 40:] * 2.5  # a box's face 0.5 m in front, its edge at column 40
    bridging, nothing = jump_figures(shown, wall)
    assert nothing == 0.0
    assert bridging == pytest.approx(100.0 * 4 / cols)  # columns 38-41 touch the edge
    holes = wall.copy()
    holes[10:20, 10:20] = np.nan  # no point here
    _, nothing = jump_figures(shown, holes)
    assert nothing == pytest.approx(100.0 * 6 * 6 / (rows * cols))  # beyond 2 samples


def test_the_jump_figure_counts_a_far_silhouette_not_a_far_wall_s_noise() -> None:
    """The measure itself at 3.75 m, where an OAK-D's depth error (0.1 px of disparity
    and 1/8 px steps: sigma 4.5 cm, steps 5.3 cm) puts neighbouring points of one wall
    more than 5 cm apart along the ray: a wall seen there at 45 deg with that noise is
    no jump; a box's face 0.3 m in front of it (0.77 px of disparity, 5 sigmas of a
    pair's noise) still is, on the samples either side of its silhouette only. The
    noise the figure allows is the sensor's (here the model's; on a real frame the one
    measured on its floor, ``disparity_noise``)."""
    rows, cols = 40, 80
    fb = 441.0 * 0.075  # an OAK-D's focal length (px) times its baseline (m)
    f = 441.0 / 1.5  # samples 1.5 depth pixels apart, as the harness takes them
    noise_px = float(np.hypot(0.1, 0.125 / np.sqrt(12.0)))
    v, u = np.mgrid[0:rows, 0:cols].astype(np.float64)
    rays = np.stack([(u - cols / 2) / f, (v - rows / 2) / f, np.ones_like(u)], -1)
    n = np.array([np.sin(np.radians(45.0)), 0.0, -np.cos(np.radians(45.0))])
    z_wall = -3.75 * n[2] / (rays @ n)  # 3.75 m ahead on the axis
    z_box = -3.45 * n[2] / (rays @ n)  # 0.3 m in front of it
    rng = np.random.default_rng(0)

    def sensed(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = np.round((fb / z + rng.normal(scale=0.1, size=z.shape)) * 8) / 8
        return rays * (fb / d)[..., None], d

    shown = np.ones((rows, cols), bool)
    wall, d_wall = sensed(z_wall)
    assert jump_figures(shown, wall)[0] > 1.0  # a fixed 5 cm rule counts the noise
    assert jump_figures(shown, wall, d_wall, noise_px)[0] < 0.2  # a 4.2-sigma pair's tail
    box, d_box = sensed(np.where(u >= 40, z_box, z_wall))
    bridging, nothing = jump_figures(shown, box, d_box, noise_px)
    assert nothing == 0.0
    # columns 38-41 touch the edge (1 or 2 samples across it); at 5 sigmas of a pair's
    # noise some of its pairs read as noise (about a third, by the normal's tail)
    assert 0.5 * 100.0 * 4 / cols <= bridging <= 100.0 * 4 / cols


class FarWall(NamedTuple):
    """A simulated frame and its truth in frame D: the wall ``normal . X = offset``
    (``normal`` towards the camera) and gravity's up."""

    frame: RealFrame
    normal: np.ndarray
    offset: float
    up: np.ndarray


def far_wall_with_boxes(seed: int) -> FarWall:
    """A simulated OAK-D frame (the nominal calibration's depth camera, pitched 10 deg
    down, 1.3 m above the floor) of a wall 3.75 m ahead turned 30 deg, two boxes 0.3
    and 0.35 m in front of it, and the floor: disparity with the sensor model's noise
    (0.1 px), its slow error (0.04 px RMS, waves of 200-400 px) and 1/8 px steps, as
    uint16 millimetres."""
    D = Calibration.default().depth
    fb = D.focal * D.baseline_m
    v, u = np.mgrid[0 : D.height, 0 : D.width].astype(np.float64)
    rays = np.stack([(u - D.K[0, 2]) / D.K[0, 0], (v - D.K[1, 2]) / D.K[1, 1], np.ones_like(u)], -1)
    t, yaw = np.radians(10.0), np.radians(30.0)
    up = np.array([0.0, -np.cos(t), -np.sin(t)])
    ahead = np.array([0.0, 0.0, 1.0]) - up[2] * up
    ahead /= np.linalg.norm(ahead)
    n = -(np.cos(yaw) * ahead + np.sin(yaw) * np.array([1.0, 0.0, 0.0]))  # to the camera
    along = np.cross(up, n)
    p0 = np.array([0.0, 0.0, 3.75])

    def plane(normal: np.ndarray, point: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore"):
            z = (normal @ point) / (rays @ normal)
        return np.where(z > 0, z, np.inf)

    z = np.minimum(plane(n, p0), plane(-up, -1.3 * up))
    for centre, width, height, off in ((-0.9, 0.5, 0.9, 0.3), (0.55, 0.4, 0.6, 0.35)):
        zb = plane(n, p0 + off * n)
        X = rays * zb[..., None]
        a, h = (X - p0) @ along, X @ up + 1.3  # along the wall, above the floor
        z = np.where((np.abs(a - centre) < width / 2) & (h > 0) & (h < height), zb, z)
    rng = np.random.default_rng(seed)
    slow = np.zeros_like(u)
    for _ in range(4):
        period, angle, phase = rng.uniform(200, 400), rng.uniform(0, np.pi), rng.uniform(0, 7)
        slow += np.cos(2 * np.pi * (u * np.cos(angle) + v * np.sin(angle)) / period + phase)
    slow *= 0.04 / np.sqrt(np.mean(slow * slow))
    d = np.round((fb / z + slow + rng.normal(scale=0.1, size=z.shape)) * 8) / 8
    with np.errstate(divide="ignore"):
        mm = np.where(d > 0, np.rint(1e3 * fb / d), 0.0)
    frame = RealFrame(
        "far-wall", mm.astype(np.uint16), D.K, "oak-d", D.baseline_m, (200, 360, 440, 400), ()
    )
    return FarWall(frame, n, float(n @ p0), up)


def test_a_far_wall_with_boxes_on_simulated_oak_d_depth() -> None:
    """The device path aimed at a wall 3.75 m away with boxes in front (the sensor model
    of an OAK-D: its steps there are 5.3 cm, its error 4.5 cm): a picture, off the
    boxes' silhouettes, upright on the wall. Its jumps are counted beyond the frame's
    own disparity noise (a fixed 5 cm counted 4.2 % of this picture as bridging). The
    upright is read on the true wall and gravity (0.7-1.2 deg on five noise draws): a
    plane fitted to the raw points there is 1-4 deg off (the sensor's slow error), and
    on it the harness's figure reads 0.2-2.4 deg for the same pictures."""
    wall = far_wall_with_boxes(1)  # a draw whose fitted plane is 3.7 deg off
    region = Region("wall", "wall-objects", (320, 170), (250, 100, 390, 200))
    fig, run = figures(wall.frame, region, render=False)
    assert fig.projected and fig.warp_ok, fig.error
    assert fig.jump_pct <= MAX_JUMP_PCT, (fig.bridging_pct, fig.no_object_pct)
    assert run.map_xy is not None
    cal = run.calibration
    R, t = cal.T_P_D[:3, :3], cal.T_P_D[:3, 3]
    n, d = R @ wall.normal, wall.offset + float((R @ wall.normal) @ t)  # the wall in frame P
    uv, real = real_samples(wall.frame, cal)
    shown_xy = run.map_xy[uv[..., 1].astype(int), uv[..., 0].astype(int)].astype(np.float64)
    with np.errstate(invalid="ignore"):
        on = np.abs(real @ n - d) < plane_tol(wall.frame, 3.75)  # the wall, not a box
    X = plane_hits(n, d, uv, cal.projector.K)
    keep = on & np.isfinite(shown_xy).all(axis=-1) & np.isfinite(X).all(axis=-1)
    J, _ = jacobians(X, keep, shown_xy)
    assert len(J) > 1000
    assert upright_error(J, n, "wall", R @ wall.up) <= UPRIGHT_DEG["wall"]
