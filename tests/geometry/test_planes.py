"""Walls snapped onto their planes (geometry/planes.py), against analytic ground truth:
noisy lattices of the analytic surfaces, ray-cast independently of the code under test."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import SurfaceError
from adaproj_edge.geometry.analytic import Corner, get_surface, ray_cast
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.planes import (
    PLANES_KEY,
    PlaneSettings,
    RawDepth,
    curvature_ratio,
    find_planes,
    fit_plane,
    fit_plane_raw,
    on_planes,
    plane_equations,
    snap_planes,
)
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface

NOISE_M = 0.0015  # about what 3 averaged stereo frames leave on the lattice at 1.5-2 m
P = Projector.default()


def truth(surface: str | Corner, shape: tuple[int, int]) -> FloatArray:
    s = get_surface(surface) if isinstance(surface, str) else surface
    return ray_cast(s, np.zeros(3), P.rays(lattice_uv(P, shape)))


def noisy(surface: str | Corner, seed: int, shape: tuple[int, int] = (21, 21)) -> Surface:
    """The lattice with depth noise along each ray (as stereo has it)."""
    pts = truth(surface, shape)
    rng = np.random.default_rng(seed)
    z = pts[..., 2] + rng.normal(scale=NOISE_M, size=pts.shape[:2])
    rays = P.rays(lattice_uv(P, shape))
    return Surface((rays * z[..., None]).astype(np.float32), P)


CONVEX_CORNER = Corner("corner-convex", x0=-0.1, z0=1.6, concave=False)


@pytest.mark.parametrize("corner", ["corner", CONVEX_CORNER], ids=["concave", "convex"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_wall_corner_becomes_its_two_walls(corner: str | Corner, seed: int) -> None:
    s = noisy(corner, seed)
    snapped, planes = snap_planes(s)
    assert len(planes) == 2
    assert snapped.shape == (161, 161)  # 8x finer: the crease lies where it is
    want = truth(corner, snapped.shape)
    got = snapped.points.astype(np.float64)
    err = np.abs(got[..., 2] - want[..., 2])
    ok = np.isfinite(err)
    assert ok.mean() > 0.95
    # the noise is gone on the walls (the frame's outer ring of cells stays interpolated)
    inner = err[4:-4, 4:-4]
    assert np.nanmedian(inner) < 0.25 * NOISE_M, np.nanmedian(inner)
    assert np.nanpercentile(inner, 95) < 0.6 * NOISE_M, np.nanpercentile(inner, 95)
    # every node stays on its own projector ray
    uv = P.project(got)
    assert np.allclose(uv[ok], lattice_uv(P, snapped.shape)[ok], atol=1e-3)
    # the meta lists the two planes (for the warp), and the snapped walls lie on them
    eq = plane_equations(snapped.meta)
    assert np.allclose(eq, [[*p.normal, p.offset] for p in planes])
    on = on_planes(got[4:-4, 4:-4].reshape(-1, 3), eq)
    assert on.any(axis=1).mean() > 0.9


@pytest.mark.parametrize(
    "bad", ["walls", [[0.0, 0.0, 1.0]], [[0.0, 0.0, 2.0, 1.0]], [[0, 0, 1, None]]]
)
def test_a_surface_whose_meta_lists_malformed_planes_is_refused(bad: object) -> None:
    with pytest.raises(SurfaceError, match=PLANES_KEY):
        plane_equations({PLANES_KEY: bad})
    assert plane_equations({}).shape == (0, 4)


@pytest.mark.parametrize(
    "name", ["cylinder-convex", "cylinder-concave", "sphere-convex", "sphere-concave", "bowl"]
)
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("sensor", [None, "oak-d"])
def test_curved_surfaces_are_left_as_they_are(name: str, seed: int, sensor: str | None) -> None:
    """Also with the sensor's noise model, which lets a plane's nodes lie a part of a
    depth step and of the sensor's slow error away from it."""
    s = noisy(name, seed)
    model = None if sensor is None else SensorModel.of(Calibration.default().depth, sensor)
    snapped, planes = snap_planes(s, sensor=model)
    assert planes == [] and snapped is s


@pytest.mark.parametrize("name", ["plane", "tilted"])
def test_a_plane_is_one_plane(name: str) -> None:
    s = noisy(name, 7)
    planes = find_planes(s)
    assert len(planes) == 1
    assert planes[0].nodes.mean() > 0.9
    # its normal is the analytic one (to a fraction of a degree)
    t = truth(name, (21, 21)).reshape(-1, 3)
    c = t.mean(axis=0)
    n_true = np.linalg.svd(t - c)[2][-1]
    assert abs(float(planes[0].normal @ n_true)) > np.cos(np.deg2rad(0.3))


def test_curvature_ratio_tells_a_noisy_plane_from_a_gentle_bend() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-0.2, 0.2, (2, 400))
    flat = np.stack([a, b, 1.5 + rng.normal(scale=0.0015, size=400)], axis=1)
    bent = flat + np.stack([0 * a, 0 * b, 0.004 * (a / 0.2) ** 2], axis=1)  # 4 mm sag
    n, d = np.array([0.0, 0.0, -1.0]), -1.5
    assert curvature_ratio(flat, n, d) < 1.1
    assert curvature_ratio(bent, n, d) > 1.5


def test_holes_and_tiny_lattices_do_not_break_it() -> None:
    s = noisy("corner", 4)
    pts = s.points.copy()
    pts[5:9, 3:12] = np.nan  # a hole in one wall
    pts[:, :2] = np.nan  # the frame's edge unseen
    snapped, planes = snap_planes(Surface(pts, P))
    assert len(planes) == 2
    assert np.isfinite(snapped.points).all(axis=-1).mean() > 0.8
    tiny = noisy("plane", 5, (3, 3))
    assert snap_planes(tiny)[1] == []  # too small to fit a window: nothing found
    empty = Surface(np.full((21, 21, 3), np.nan, np.float32), P)
    assert snap_planes(empty) == (empty, [])


def _plane_depths(rays: FloatArray, n: FloatArray, d: float) -> FloatArray:
    """Depth (z) where rays (..., 3; z = 1) meet the plane ``n . X = d``."""
    return d / (rays @ n)


def test_a_cell_an_object_s_edge_runs_through_takes_the_wall_where_its_raw_depth_is() -> None:
    """A box's face 15 cm in front of a wall, its edges through the middle of lattice
    cells: those cells have corners on the wall and on the box, and were interpolated
    across the edge, a slope on which content was shown distorted (the partition's edge
    on a real Kinect frame). Given the raw depth (a lattice 4x finer, 3 mm of noise),
    the wall's part of each such cell lies on the wall: within 1 mm of the analytic
    wall (the fitted plane's own error from ~6000 raw points with 3 mm noise is ~0.1 mm;
    the slope it replaces is 2 cm off there)."""
    n = np.array([0.1, 0.2, -1.0]) / np.linalg.norm([0.1, 0.2, -1.0])
    d = float(n @ [0.0, 0.0, 2.7])
    rows, cols, k = 21, 21, 4

    def depth(shape: tuple[int, int]) -> tuple[FloatArray, FloatArray, FloatArray]:
        uv = lattice_uv(P, shape)
        rays = P.rays(uv)
        wall = _plane_depths(rays, n, d)
        # the box: rays right of 0.71 and below 0.63 of the frame (mid-cell edges)
        box = (uv[..., 0] > 0.71 * P.width) & (uv[..., 1] > 0.63 * P.height)
        return rays, np.where(box, _plane_depths(rays, n, d - 0.15), wall), box

    rays, z, _ = depth((rows, cols))
    surface = Surface((rays * z[..., None]).astype(np.float32), P)
    fine = ((rows - 1) * k + 1, (cols - 1) * k + 1)
    raw_rays, raw_z, _ = depth(fine)
    raw_z = raw_z + np.random.default_rng(3).normal(scale=0.003, size=raw_z.shape)
    raw = RawDepth(raw_rays * raw_z[..., None], k)

    before, planes = snap_planes(surface)
    after, planes_raw = snap_planes(surface, raw=raw)
    assert len(planes) == len(planes_raw) == 1
    _, want, box = depth(after.shape)
    # the fine nodes on the wall in the cells the box's edge runs through, beyond the
    # raw sample nearest the edge (which may vote either way)
    r8, c8 = np.arange(after.shape[0]) // 8, np.arange(after.shape[1]) // 8
    _, _, box_nodes = depth((rows, cols))
    corners = np.stack(
        [
            box_nodes[np.minimum(r8 + a, rows - 1)[:, None], np.minimum(c8 + b, cols - 1)[None, :]]
            for a in (0, 1)
            for b in (0, 1)
        ]
    )
    mixed = corners.any(axis=0) & ~corners.all(axis=0)
    clear = ~ndimage.binary_dilation(box, structure=np.ones((7, 7), bool))  # 1.5 raw samples
    wall_edge = mixed & clear
    assert wall_edge.sum() > 50
    err_after = np.abs(after.points[..., 2].astype(np.float64) - want)[wall_edge]
    err_before = np.abs(before.points[..., 2].astype(np.float64) - want)[wall_edge]
    assert err_after.max() < 0.001
    assert err_before.max() > 0.01  # the slope across the edge, without the raw depth


def test_a_small_far_plane_is_fitted_to_its_raw_points_robustly() -> None:
    """A wardrobe's side at 3.4-3.8 m, 47 deg from the view, seen by a Kinect-class
    sensor (disparity noise and 1/8 px steps: ~3 cm of depth error there), a fifth of
    the points on an object 30 cm in front of it, and a start 10 deg off (the plane of
    the smoothed lattice there): the plane fitted to the raw points is within 1 deg of
    the truth (the expected error of 5000 points with that noise over the side's
    0.4 m is ~0.2 deg), and passes within 1 cm of the side's centre. A least-squares
    fit of all the points is pulled far off by the object."""
    sensor = SensorModel("kinect", 580.0, 0.075, 3, 0.07, 0.04)
    a = np.deg2rad(47.0)
    n_true = np.array([-np.sin(a), 0.0, -np.cos(a)])
    centre = np.array([-0.9, -0.1, 3.6])
    rng = np.random.default_rng(5)
    e1 = np.array([np.cos(a), 0.0, -np.sin(a)])  # across the side, in its plane
    m = 6000
    s, t = rng.uniform(-0.25, 0.25, m), rng.uniform(-0.5, 0.5, m)
    X = centre + s[:, None] * e1 + t[:, None] * np.array([0.0, 1.0, 0.0])
    X[s > 0.15] -= 0.3 * n_true  # an object in front of its near fifth
    rays = X / X[:, 2:3]
    disparity = sensor.fb / X[:, 2] + rng.normal(scale=sensor.disparity_sigma_px, size=m)
    z = sensor.fb / (np.round(disparity * 8) / 8)  # the sensor's 1/8 px steps
    raw = rays * z[:, None]
    n_all, _ = fit_plane(raw)
    assert np.degrees(np.arccos(abs(float(n_all @ n_true)))) > 10.0
    turn = np.deg2rad(10.0)  # the start: turned 10 deg about the vertical
    n0 = np.array(
        [
            n_true[0] * np.cos(turn) + n_true[2] * np.sin(turn),
            0.0,
            -n_true[0] * np.sin(turn) + n_true[2] * np.cos(turn),
        ]
    )
    n, d = fit_plane_raw(raw, sensor, n0, float(n0 @ centre))
    assert np.degrees(np.arccos(abs(float(n @ n_true)))) < 1.0
    assert abs(float(n @ centre) - d) < 0.01


@pytest.mark.parametrize("corner", ["corner", CONVEX_CORNER], ids=["concave", "convex"])
def test_the_depth_mixed_across_a_crease_does_not_move_it(corner: str | Corner) -> None:
    """Exact walls seen by a sensor that makes each pixel's depth from a window of the
    image (the mean over its footprint, +-3 px along the row, of the true depth): the
    raw points within that of the crease mix both walls' depths (5-6 mm off at 1.8 m,
    all to one side) and, fitted with the rest, moved the walls' crease 0.3-0.8 mm.
    Left out of the fit, it is where it is: within 0.1 mm (exact walls; what is left is
    the window's mean of depth across an oblique wall, a few hundredths of a mm off
    it). The model has no random error and 8 subpixel bits, so neither noise nor the
    staircase hides the bias; its footprint, focal length and slow error are an
    OAK-D's (the slow error, 4 mm at 1.8 m, is why the robust weights keep the mixed
    points: they are within it of both walls)."""
    c = get_surface(corner) if isinstance(corner, str) else corner
    assert isinstance(c, Corner)
    oak = SensorModel.of(Calibration.default().depth)
    sensor = SensorModel(
        "oak-d", oak.focal_px, oak.baseline_m, 8, 0.0, oak.bias_px, oak.footprint_px
    )
    k, foot = 3, int(sensor.footprint_px)
    rays = P.rays(lattice_uv(P, (61, 61)))
    window = [
        ray_cast(c, np.zeros(3), rays + np.array([j / sensor.focal_px, 0.0, 0.0]))[..., 2]
        for j in range(-foot, foot + 1)
    ]
    raw = rays * np.mean(window, axis=0)[..., None]
    surface = Surface(raw[::k, ::k].astype(np.float32), P)
    planes = find_planes(surface, PlaneSettings(raw_fit=True), sensor, RawDepth(raw, k))
    assert len(planes) == 2
    eq = np.array([[*p.normal, p.offset] for p in planes])
    x, z = np.linalg.solve(eq[:, [0, 2]], eq[:, 3])  # the crease at y = 0
    assert np.hypot(x - c.x0, z - c.z0) < 1e-4


OAK = SensorModel.of(Calibration.default().depth)
RAW_K = 3  # the raw depth's lattice is this much finer than the surface's


def sensed(
    z_true: FloatArray, bias_px: FloatArray, seed: int
) -> tuple[Surface, RawDepth, FloatArray]:
    """What an OAK-D makes of the true depth ``z_true`` (61, 61) along the raw lattice's
    projector rays: its disparity plus a slow error ``bias_px`` (61, 61) plus its random
    error, in 1/8 px steps; the surface's lattice (21, 21) every third ray, each node the
    mean depth of the 3 x 3 raw points around it (a lattice smooths). Also the rays."""
    rays = P.rays(lattice_uv(P, z_true.shape))
    rng = np.random.default_rng(seed)
    disparity = OAK.fb / z_true + bias_px
    disparity += rng.normal(scale=OAK.disparity_sigma_px, size=z_true.shape)
    z = OAK.fb / (np.round(disparity * 8.0) / 8.0)
    node_z = ndimage.uniform_filter(z, RAW_K, mode="nearest")[::RAW_K, ::RAW_K]
    nodes = rays[::RAW_K, ::RAW_K] * node_z[..., None]
    return Surface(nodes.astype(np.float32), P), RawDepth(rays * z[..., None], RAW_K), rays


def _halves_apart(rays: FloatArray, left: NDArray[np.bool_]) -> float:
    """Distance in normalised image coordinates between the centroids of the rays
    (z = 1) of ``left`` and of the rest."""
    return float(np.linalg.norm(rays[left][:, :2].mean(axis=0) - rays[~left][:, :2].mean(axis=0)))


@pytest.mark.parametrize(
    ("shape", "turn"), [("bowl", 30), ("curl", 30), ("saddle", 30), ("tent", 30), ("tent", 0)]
)
def test_a_flat_wall_the_sensor_bends_is_one_plane(shape: str, turn: float) -> None:
    """A flat wall 2.5 m away turned ``turn`` deg, seen by an OAK-D whose slow disparity
    error bends it by 0.8 of the curvature its model allows (``curve_px``, measured on
    real Kinect-class frames: tools/measure_sensor_bend.py): a bowl, a curl along the
    rows, a saddle, and a tent (two flat halves tilted apart by 0.8 of the dihedral the
    model allows between them: 12 deg turned 30 deg, 14 facing). Before, the device
    found no plane over the wall (each piece bent more than the slow error's RMS
    allows, or one piece), and on the tent facing it two planes with a crease between.
    It is one plane over nearly every node, its normal the true one: every shape is
    symmetric about the image's centre, so none tilts the wall as a whole (the normal's
    error of ~9000 raw points with 0.1 px of noise is ~0.05 deg; 0.5 deg allowed)."""
    n_true = np.array([np.sin(np.deg2rad(turn)), 0.0, -np.cos(np.deg2rad(turn))])
    d_true = float(n_true @ [0.0, 0.0, 2.5])
    rays = P.rays(lattice_uv(P, (61, 61)))
    x, y = rays[..., 0], rays[..., 1]
    kappa = 0.8 * OAK.curve_px
    half = float(x.max())
    bias = {
        "bowl": kappa * (x * x + y * y),
        "curl": kappa * x * x,
        "saddle": kappa * (x * x - y * y),
        # halves' gradients 2 g apart, their centroids ``half`` apart: 0.8 of the model's
        "tent": kappa * half * np.abs(x),
    }[shape]
    if shape == "tent":
        limit = OAK.max_dihedral_rad(abs(d_true), _halves_apart(rays, x < 0))
        assert np.rad2deg(limit) > 10.0  # what the test asks of the model is not small
    surface, raw, _ = sensed(d_true / (rays @ n_true), bias, seed=1)
    planes = find_planes(surface, PlaneSettings(), OAK, raw)
    assert len(planes) == 1, [int(p.nodes.sum()) for p in planes]
    assert planes[0].nodes.mean() > 0.95
    assert np.rad2deg(np.arccos(abs(float(planes[0].normal @ n_true)))) < 0.5
    before = find_planes(surface, PlaneSettings(curve_tolerance=0.0), OAK, raw)
    assert len(before) != 1 or before[0].nodes.mean() < 0.5
    assert len(before) == 2 or turn != 0


@pytest.mark.parametrize("concave", [True, False], ids=["concave", "convex"])
@pytest.mark.parametrize("times", [1.5, 0.6])
def test_a_shallow_corner_is_a_crease_where_the_sensor_resolves_it(
    concave: bool, times: float
) -> None:
    """A corner 1.8 m away whose walls meet at ``times`` the dihedral an OAK-D's slow
    error can put between them (its model's ``max_dihedral_rad`` for the walls' distance
    and the distance of their centroids in the image: 10.2 deg, so a 165 deg corner at
    1.5 times, 174 deg at 0.6), seen with the sensor's noise and steps but no slow
    error. At 1.5 times it is two planes, each within 1 deg of its wall; at 0.6 times
    it is one (the sensor cannot tell it from a wall it bends)."""
    rays = P.rays(lattice_uv(P, (61, 61)))
    flat = Corner("flat", x0=0.0, z0=1.8, half_angle=np.pi / 2, concave=concave)
    limit = OAK.max_dihedral_rad(1.8, _halves_apart(rays, rays[..., 0] < 0))
    corner = Corner(
        "shallow", x0=0.0, z0=1.8, half_angle=(np.pi - times * limit) / 2, concave=concave
    )
    assert flat.half_angle > corner.half_angle
    z = ray_cast(corner, np.zeros(3), rays)[..., 2]
    surface, raw, _ = sensed(z, np.zeros_like(z), seed=2)
    planes = find_planes(surface, PlaneSettings(), OAK, raw)
    if times < 1.0:
        assert len(planes) == 1
        return
    assert len(planes) == 2
    a = corner.half_angle
    for p in planes:  # each wall's normal: (cos a, 0, sin a) turned to either side
        side = np.sign(float(p.nodes[:, -1].sum() - p.nodes[:, 0].sum()))
        tangent = np.array([side * np.sin(a), 0.0, -np.cos(a) if concave else np.cos(a)])
        n_true = np.cross(tangent, [0.0, 1.0, 0.0])
        n_true /= np.linalg.norm(n_true)
        assert np.rad2deg(np.arccos(abs(float(p.normal @ n_true)))) < 1.0
