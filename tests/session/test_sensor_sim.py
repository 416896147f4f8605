"""The simulator's real-sensor depth (session/stereo.py ``StereoNoise.of_sensor``) and
cluttered scenes (session/clutter.py): steps of the predicted size, occlusion bands on
the side the other camera cannot see, flying pixels and holes; the expectations are
computed here from the geometry, not from the code under test."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.session.clutter import CLUTTER
from adaproj_edge.session.simulator import Scene
from adaproj_edge.session.stereo import StereoNoise, normals_cos, stereo_depth

CAL = Calibration.default()
D = CAL.depth
FB = D.focal * D.baseline_m
SENSOR = SensorModel.of(D, "oak-d")
NOISE = StereoNoise.of_sensor(SENSOR)


def seen(scene: Scene) -> np.ndarray:
    return scene.points_seen(D.K, D.width, D.height, np.eye(3), np.zeros(3))


def tilted_wall(z0: float, tilt_deg: float) -> np.ndarray:
    v, u = np.mgrid[0 : D.height, 0 : D.width].astype(float)
    rays = np.stack([(u - D.K[0, 2]) / D.K[0, 0], (v - D.K[1, 2]) / D.K[1, 1], np.ones_like(u)], -1)
    t = np.radians(tilt_deg)
    n = np.array([np.sin(t), 0.0, -np.cos(t)])
    s = (n @ np.array([0.0, 0.0, z0])) / (rays @ n)
    return rays * s[..., None]


@pytest.mark.parametrize("z0", [1.5, 2.5])
def test_a_wall_is_a_staircase_of_the_predicted_steps(z0: float) -> None:
    pts = tilted_wall(z0, 35.0)
    depth = stereo_depth(pts, D, NOISE, np.random.default_rng(1)).astype(float) / 1000
    row = depth[200, 280:360]
    values = np.unique(row[row > 0])
    assert values.size >= 3
    steps = np.diff(values)
    # neighbouring levels one disparity step apart: z^2 / (f B 8) at their depth
    want = values[:-1] * values[1:] / (FB * 8)
    ratio = steps / want
    assert np.median(ratio) == pytest.approx(1.0, abs=0.05)
    assert np.all(ratio > 0.9)
    # the whole frame: depths of disparities on the 1/8 px grid (to the millimetre)
    ok = depth > 0
    k = np.round(FB / depth[ok] * 8)
    assert np.mean(np.abs(np.round(FB / (k / 8) * 1000) / 1000 - depth[ok]) < 1.5e-3) > 0.95
    # the random error per pixel is the device's model of it (the simulator once drew
    # half of it): the disparity's spread about the true wall (1.4826 x its median
    # absolute deviation, as tests/realframes.py's disparity_noise reads a real frame)
    # within 15 % of the model's disparity_total_px (~10^5 pixels, correlated over the
    # 3 px footprint: the estimate's own error is ~1 %; the 5 x 5 median the device
    # applies takes a few % off a field correlated over 3 px)
    r = FB / depth[ok] - FB / pts[..., 2][ok]
    spread = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    assert spread == pytest.approx(SENSOR.disparity_total_px, rel=0.15)


def test_the_occlusion_band_is_left_of_a_box_and_its_width_the_disparity_jump() -> None:
    scene = Scene.load("wall-boxes")
    pts = seen(scene)
    depth = stereo_depth(pts, D, NOISE, np.random.default_rng(2), pts)
    row = 250
    z = pts[row, :, 2]
    on_box = np.nonzero(z < 2.35)[0]  # the box's front face (1.5 m) and a side face
    c0, c1 = int(on_box.min()), int(on_box.max())
    assert abs(z[c0] - 1.5) < 1e-6  # its left silhouette is the front face's edge
    assert np.all(np.abs(z[c0 - 30 : c0] - 2.4) < 1e-6)  # the wall left of the box
    assert np.all(np.abs(z[c1 + 1 : c1 + 30] - 2.4) < 1e-6)  # and right of it
    band = round(FB / 1.5 - FB / 2.4)  # pixels of wall the right camera cannot see
    assert band >= 6
    left = depth[row - 5 : row + 6, c0 - band + 1 : c0 - 1]
    right = depth[row - 5 : row + 6, c1 + 3 : c1 + band]
    assert np.mean(left == 0) > 0.95  # hidden: no depth
    assert np.mean(right > 0) > 0.8  # seen by both cameras
    # the smooth model (no occlusion) does not leave that band empty
    smooth = stereo_depth(pts, D, StereoNoise(), np.random.default_rng(2), pts)
    assert np.mean(smooth[row - 5 : row + 6, c0 - band + 1 : c0 - 3] > 0) > 0.5


def test_flying_pixels_lie_between_the_two_sides_of_a_jump() -> None:
    pts = seen(Scene.load("wall-boxes"))
    depth = stereo_depth(pts, D, NOISE, np.random.default_rng(3), pts).astype(float) / 1000
    z = pts[..., 2]
    fliers = (depth > 0) & (np.abs(depth - z) > 0.1)
    jump = np.zeros(z.shape, bool)
    jx = np.abs(np.diff(z, axis=1)) > 0.2
    jy = np.abs(np.diff(z, axis=0)) > 0.2
    jump[:, 1:] |= jx
    jump[:, :-1] |= jx
    jump[1:] |= jy
    jump[:-1] |= jy
    near = np.zeros_like(jump)  # within 3 px of a silhouette
    for dy in range(-3, 4):
        for dx in range(-3, 4):
            near |= np.roll(np.roll(jump, dy, axis=0), dx, axis=1)
    assert fliers.sum() > 20
    assert np.mean(near[fliers]) > 0.95  # at silhouettes, not on the faces
    lo = ndimage.minimum_filter(z, size=7)[fliers]
    hi = ndimage.maximum_filter(z, size=7)[fliers]
    assert np.mean((depth[fliers] > lo - 0.05) & (depth[fliers] < hi + 0.05)) > 0.95
    # the smooth model leaves none
    smooth = stereo_depth(pts, D, StereoNoise(), np.random.default_rng(3), pts) / 1000
    assert np.sum((smooth > 0) & (np.abs(smooth - z) > 0.1)) < 0.2 * fliers.sum()


def test_untextured_patches_have_no_depth() -> None:
    pts = tilted_wall(2.0, 0.0)
    with_holes = stereo_depth(pts, D, NOISE, np.random.default_rng(4), pts)
    without = stereo_depth(pts, D, NOISE, np.random.default_rng(4))
    lost = np.mean((without > 0) & (with_holes == 0))
    assert 0.01 < lost < 0.08


@pytest.mark.parametrize("name", sorted(CLUTTER))
def test_cluttered_scenes_show_several_depths(name: str) -> None:
    pts = seen(Scene.load(name))
    z = pts[..., 2]
    assert np.isfinite(z).mean() > 0.95
    # something stands in front of the wall: a jump of more than 25 cm between neighbours
    jumps = np.abs(np.diff(z, axis=1))
    assert np.nanmax(jumps) > 0.25


def test_normals_cos_on_a_plane_is_the_angle_of_its_normal() -> None:
    """On a plane every difference of two points lies in the plane, so the cross product
    of the point map's gradients is the plane's normal n to rounding, and the |cos|
    is |n . p| / |p|: the points are ~2 m apart by ~5 mm, so the gradients carry a
    relative rounding of ~1e-13 and 1e-9 is far above it. NaN points have no cos,
    nor do their neighbours along a row or a column (the central differences')."""
    pts = tilted_wall(2.0, 35.0)
    pts[100:110, 200:300] = np.nan
    cos = normals_cos(pts)
    n = np.array([np.sin(np.radians(35.0)), 0.0, -np.cos(np.radians(35.0))])
    truth = np.abs(pts @ n) / np.linalg.norm(pts, axis=-1)
    ok = np.isfinite(truth)
    cross = ndimage.generate_binary_structure(2, 1)
    assert np.array_equal(np.isfinite(cos), ndimage.binary_erosion(ok, cross, border_value=1))
    assert np.abs(cos - truth)[np.isfinite(cos)].max() < 1e-9
