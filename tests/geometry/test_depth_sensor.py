"""The depth pipeline on what a real sensor gives: quantised walls come out flat, and a
box in front of a wall is cut at its silhouette (geometry/depth/sensor.py, cuts.py, the
step floor of fits.py, planes.py with a sensor model).

The depth frames are made here, independently of the session simulator: true depth of
planes and boxes, its disparity rounded to the sensor's 1/8 px steps (a real OAK-D's
staircase), the band beside a silhouette that one camera does not see left empty.
"""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.geometry.depth.cuts import cut_at_jumps, cut_lattice, keep_aimed_piece
from adaproj_edge.geometry.depth.estimate import SurfaceEstimator
from adaproj_edge.geometry.depth.images import clean_images
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.depth.workspace import Workspace
from adaproj_edge.geometry.planes import snap_planes

CAL = Calibration.default()
D = CAL.depth
FB = D.focal * D.baseline_m


def depth_rays() -> FloatArray:
    """Rays (h, w, 3) with z = 1 of every depth pixel."""
    v, u = np.mgrid[0 : D.height, 0 : D.width].astype(np.float64)
    return np.stack([(u - D.K[0, 2]) / D.K[0, 0], (v - D.K[1, 2]) / D.K[1, 1], np.ones_like(u)], -1)


def plane_depth(rays: FloatArray, normal: FloatArray, point: FloatArray) -> FloatArray:
    """Depth (z) along ``rays`` (z = 1) of the plane through ``point`` with ``normal``."""
    with np.errstate(divide="ignore"):
        z = (normal @ point) / (rays @ normal)
    return np.where(z > 0, z, np.nan)


def quantised(
    z: FloatArray,
    bits: int = 3,
    jitter_px: float = 0.0,
    seed: int = 0,
    bias_px: FloatArray | float = 0.0,
) -> FloatArray:
    """Depth as the sensor reports it: disparity (with ``jitter_px`` of noise and a
    slowly varying error ``bias_px`` added) rounded to 1 / 2^bits px, in millimetres;
    NaN stays NaN. Without jitter the steps are as clean as a real OAK-D's after its
    median filter."""
    rng = np.random.default_rng(seed)
    d = FB / z + bias_px + rng.normal(scale=jitter_px, size=z.shape)
    q = np.round(d * 2**bits) / 2**bits
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.round(FB / q * 1000.0) / 1000.0
    return np.where(np.isfinite(z) & (q > 0), out, np.nan)


def lattice_truth(normal_d: FloatArray, point_d: FloatArray, shape: tuple[int, int]) -> FloatArray:
    """True points (rows, cols, 3) in frame P where the lattice's rays meet a plane given
    in frame D."""
    R, t = CAL.T_P_D[:3, :3], CAL.T_P_D[:3, 3]
    n, c = R @ normal_d, R @ point_d + t
    rays = CAL.projector.rays(lattice_uv(CAL.projector, shape))
    return rays * plane_depth(rays, n, c)[..., None]


def angle_distortion(est: FloatArray, truth: FloatArray) -> FloatArray:
    """Per lattice triangle: sigma1 / sigma2 - 1 of the map from the estimated triangle to
    the true one (what content laid out undistorted on the estimate shows on the truth)."""
    out = []
    rows, cols = est.shape[:2]
    for corners in (((0, 0), (0, 1), (1, 1)), ((0, 0), (1, 1), (1, 0))):
        e = [est[i : rows - 1 + i, j : cols - 1 + j] for i, j in corners]
        t = [truth[i : rows - 1 + i, j : cols - 1 + j] for i, j in corners]
        E = np.stack([e[1] - e[0], e[2] - e[0]], -1).reshape(-1, 3, 2)
        T = np.stack([t[1] - t[0], t[2] - t[0]], -1).reshape(-1, 3, 2)
        ok = np.isfinite(E).all(axis=(1, 2)) & np.isfinite(T).all(axis=(1, 2))
        re, rt = np.linalg.qr(E[ok])[1], np.linalg.qr(T[ok])[1]
        sv = np.linalg.svd(rt @ np.linalg.inv(re), compute_uv=False)
        out.append(sv[:, 0] / sv[:, 1] - 1.0)
    return np.concatenate(out)


# --- the noise model ---------------------------------------------------------------------


def test_step_and_sigma_follow_the_formula() -> None:
    model = SensorModel.of(D, "oak-d")
    assert model.focal_px == D.focal and model.baseline_m == D.baseline_m
    for z in (1.25, 2.5, 4.0):
        assert model.step_m(z) == pytest.approx(z * z / (D.focal * D.baseline_m * 8), rel=1e-12)
    # about 6 mm at 1.25 m and 24 mm at 2.5 m for the nominal OAK-D
    assert 0.005 < model.step_m(1.25) < 0.007 and 0.021 < model.step_m(2.5) < 0.026
    # the step in inverse depth is the same at every depth
    z = np.array([1.0, 2.0, 3.0])
    assert np.allclose(model.step_m(z) / z**2, model.inverse_step)
    # sigma: the matcher's noise and the step's (uniform: step / sqrt 12), grown with z^2
    want = np.hypot(0.1, 0.125 / np.sqrt(12))
    assert model.sigma_m(2.0) == pytest.approx(4.0 / (D.focal * D.baseline_m) * want)
    assert model.sigma_m(3.0) / model.sigma_m(1.5) == pytest.approx(4.0)
    # a unit's own calibration: its focal and baseline; a Kinect-class sensor
    other = DepthCameraModel(np.array([[580.0, 0, 320], [0, 580.0, 240], [0, 0, 1]]), 640, 480)
    kinect = SensorModel.of(other, "kinect")
    assert kinect.step_m(2.5) == pytest.approx(2.5**2 / (580 * 0.075 * 8))
    with pytest.raises(InputError):
        SensorModel.of(D, "lidar")


# --- part 3: a quantised wall is flat ----------------------------------------------------


@pytest.mark.parametrize("z0", [1.5, 2.5, 3.0])
@pytest.mark.parametrize("tilt_deg", [25.0, 50.0])
def test_a_quantised_wall_comes_out_planar(z0: float, tilt_deg: float) -> None:
    t = np.radians(tilt_deg)
    normal, point = np.array([np.sin(t), 0.0, -np.cos(t)]), np.array([0.0, 0.0, z0])
    z = quantised(plane_depth(depth_rays(), normal, point), seed=int(z0 * 10 + tilt_deg))
    steps = np.unique(np.round(z[200, 300:340] * 1000))
    assert steps.size >= 2  # the frame is a staircase
    estimator = SurfaceEstimator(CAL)
    est = estimator.estimate(z, (21, 21))
    snapped, planes = snap_planes(est.surface, sensor=estimator.sensor)
    assert len(planes) == 1
    truth = lattice_truth(normal, point, snapped.shape)
    got = snapped.points.astype(np.float64)
    assert np.isfinite(got[..., 2]).mean() > 0.6
    assert np.mean(angle_distortion(got, truth)) <= 0.02


# the slowly varying disparity error of the real Kinect-class frames (tests/fixtures/real):
# 0.02-0.045 px RMS over a floor or a wall, averaged over 16 x 16 pixel blocks
WARP_PX = 0.04


def warp_px(rms_px: float, seed: int) -> FloatArray:
    """A slowly varying disparity error (h, w) of RMS ``rms_px``: four plane waves of
    200-400 px periods in random directions and phases, as real structured-light and
    stereo sensors warp a flat wall (bands and bowls a few hundred pixels across)."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0 : D.height, 0 : D.width].astype(np.float64)
    b = np.zeros_like(u)
    for _ in range(4):
        period, angle, phase = rng.uniform(200, 400), rng.uniform(0, np.pi), rng.uniform(0, 7)
        b += np.cos(2 * np.pi * (u * np.cos(angle) + v * np.sin(angle)) / period + phase)
    b -= b.mean()
    return rms_px * b / np.sqrt(np.mean(b * b))


@pytest.mark.parametrize("z0, tilt_deg", [(2.0, 30.0), (3.0, 60.0)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_wall_warped_by_the_sensor_s_slow_error_is_snapped_onto_its_plane(
    z0: float, tilt_deg: float, seed: int
) -> None:
    """A wall whose disparity carries the slow error of a real sensor (the RMS the
    Kinect-class frames of ``tests/fixtures/real`` show) is one plane: snapped whole,
    it shows the content undistorted on the true wall. Distortion against the wall's
    ray-cast truth; the lattice that follows the error shows 0.01-0.02."""
    t = np.radians(tilt_deg)
    normal, point = np.array([np.sin(t), 0.0, -np.cos(t)]), np.array([0.0, 0.0, z0])
    z = quantised(plane_depth(depth_rays(), normal, point), bias_px=warp_px(WARP_PX, seed))
    estimator = SurfaceEstimator(CAL)
    est = estimator.estimate(z, (21, 21))
    snapped, planes = snap_planes(est.surface, sensor=estimator.sensor)
    assert len(planes) == 1
    assert planes[0].nodes.mean() > 0.85
    got = snapped.points.astype(np.float64)
    truth = lattice_truth(normal, point, snapped.shape)
    assert np.isfinite(got[..., 2]).mean() > 0.6
    assert np.mean(angle_distortion(got, truth)) <= 0.015


def bump_depth(z0: float, height: float, sigma: float) -> FloatArray:
    """Depth (h, w) of a frontal wall ``z0`` away with a round bump ``height`` towards the
    camera (Gaussian, ``sigma`` metres wide) under the projector's axis."""
    rays = depth_rays()
    x, y = rays[..., 0] * z0, rays[..., 1] * z0  # (to first order: the bump is shallow)
    cx, cy = -CAL.T_P_D[0, 3], -CAL.T_P_D[1, 3]  # the projector's centre in D
    return z0 - height * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sigma**2))


def test_a_shallow_bump_on_a_wall_is_not_snapped_flat() -> None:
    """A bump 1 cm high (a Gaussian 5 cm wide, sigma) on a wall 1.2 m away, seen by the
    quantised sensor (steps of 5 mm there): the surface shows two thirds of it, and
    the snapping, which now allows a node the sensor's slow error on top of its step,
    leaves the bump out of the wall's plane (twice that allowance would flatten it)."""
    z0, height = 1.2, 0.01
    z = quantised(bump_depth(z0, height, 0.05))
    estimator = SurfaceEstimator(CAL)
    est = estimator.estimate(z, (21, 21))
    snapped, planes = snap_planes(est.surface, sensor=estimator.sensor)
    assert len(planes) == 1  # the wall around it
    # the bump's height along the projector's axis (the lattice's centre) against the
    # wall's: the surface's depth there, before and after the snapping
    rows, cols = snapped.shape
    wall = z0 + CAL.T_P_D[2, 3]
    before = wall - float(est.surface.points[10, 10, 2])
    after = wall - float(snapped.points[rows // 2, cols // 2, 2])
    assert before > 0.5 * height  # the estimate sees it
    assert after > 0.9 * before  # and the snapping keeps it
    assert not planes[0].nodes[9:12, 9:12].any()


# --- part 2: a box in front of a wall is cut at its silhouette ----------------------------

WALL_Z = 2.5


def box_scene(cx: float) -> tuple[FloatArray, FloatArray]:
    """Depth frame (h, w) of a box (front face 0.5 x 0.4 m at 1.6 m, centred at x =
    ``cx``) in front of a frontal wall at 2.5 m, quantised, with the band of the wall
    beside the box that the right camera does not see left empty; and the box's
    extent (x0, x1, y0, y1, z) in frame D."""
    rays = depth_rays()
    box = np.array([cx - 0.25, cx + 0.25, -0.2, 0.2, 1.6])
    z = np.full(rays.shape[:2], WALL_Z)
    x, y = rays[..., 0] * box[4], rays[..., 1] * box[4]
    on_box = (x >= box[0]) & (x <= box[1]) & (y >= box[2]) & (y <= box[3])
    z[on_box] = box[4]
    # the right camera (baseline to the right) cannot see the wall just left of the box:
    # the wall pixels whose point, seen from the right camera, is behind the box
    xr = rays[..., 0] * WALL_Z - D.baseline_m  # the wall point in the right camera
    u_r = xr / WALL_Z  # its ray there; the box's edges seen from the right camera:
    lo, hi = (box[0] - D.baseline_m) / box[4], (box[1] - D.baseline_m) / box[4]
    yy = rays[..., 1] * WALL_Z / box[4]
    hidden = ~on_box & (u_r >= lo) & (u_r <= hi) & (np.abs(yy * box[4]) <= 0.2)
    z[hidden] = np.nan
    return quantised(z), box


def node_labels(box: FloatArray, shape: tuple[int, int]) -> FloatArray:
    """1 where the lattice's projector ray meets the box first, 0 where the wall."""
    R, t = CAL.T_P_D[:3, :3], CAL.T_P_D[:3, 3]
    rays_p = CAL.projector.rays(lattice_uv(CAL.projector, shape))
    rays_d = rays_p @ R  # directions in D; the projector's centre in D:
    o = -R.T @ t
    s = (box[4] - o[2]) / rays_d[..., 2]
    x, y = o[0] + s * rays_d[..., 0], o[1] + s * rays_d[..., 1]
    return ((x >= box[0]) & (x <= box[1]) & (y >= box[2]) & (y <= box[3])).astype(float)


def spanning_triangles(z: FloatArray, labels: FloatArray) -> int:
    """Lattice triangles with every corner known whose corners lie on different sides."""
    n = 0
    rows, cols = z.shape
    for corners in (((0, 0), (0, 1), (1, 1)), ((0, 0), (1, 1), (1, 0))):
        zs = np.stack([z[i : rows - 1 + i, j : cols - 1 + j] for i, j in corners])
        ls = np.stack([labels[i : rows - 1 + i, j : cols - 1 + j] for i, j in corners])
        known = np.isfinite(zs).all(axis=0)
        n += int(np.sum(known & (ls.min(axis=0) != ls.max(axis=0))))
    return n


@pytest.mark.parametrize("shape", [(21, 21), (41, 61)])
def test_a_box_under_the_aim_is_kept_and_the_wall_cut_off(shape: tuple[int, int]) -> None:
    z, box = box_scene(0.0)
    est = SurfaceEstimator(CAL).estimate(z, shape)
    got = est.surface.points[..., 2].astype(np.float64)
    labels = node_labels(box, shape)
    known = np.isfinite(got)
    assert spanning_triangles(got, labels) == 0
    assert known.any() and np.all(labels[known] == 1)  # the box: the piece under the aim
    assert known.sum() >= 0.8 * labels.sum()  # most of the box's face
    # and its nodes are on the box's face, not pulled toward the wall behind
    dev = np.abs(est.surface.points[..., 2][known] - 1.6 - CAL.T_P_D[2, 3])
    assert np.median(dev) < 0.01 and np.max(dev) < 0.05  # (the edge nodes: a few cm)


def test_a_wall_under_the_aim_is_kept_without_a_curtain() -> None:
    shape = (21, 21)
    z, box = box_scene(0.55)  # the box off to the right; the aim on the wall
    est = SurfaceEstimator(CAL).estimate(z, shape)
    got = est.surface.points[..., 2].astype(np.float64)
    labels = node_labels(box, shape)
    known = np.isfinite(got)
    assert labels.sum() > 10  # the projector sees the box
    assert spanning_triangles(got, labels) == 0
    assert np.all(labels[known] == 0)
    assert known.sum() >= 0.8 * (labels == 0).sum()
    # nothing between the two depths (no curtain, no filled occlusion band)
    zp = est.surface.points[..., 2][known]
    assert np.all(np.abs(zp - WALL_Z - CAL.T_P_D[2, 3]) < 0.05)


def test_without_cuts_the_surface_spans_the_silhouette() -> None:
    """What the cuts remove (and what the pipeline did before them)."""
    z, box = box_scene(0.55)
    est = SurfaceEstimator(CAL, DepthSettings(cut=False)).estimate(z, (21, 21))
    got = est.surface.points[..., 2].astype(np.float64)
    assert spanning_triangles(got, node_labels(box, (21, 21))) > 0


def test_the_aimed_piece_is_kept_unless_it_is_a_sliver_of_the_largest() -> None:
    # a lattice in three pieces: a wall (left, 60 nodes), a box (right, 24 nodes) and a
    # chair leg (a column of 3 nodes), separated by unknown columns
    s = np.full((6, 20), np.nan)
    s[:, 0:10] = 2.5
    s[:, 11:15] = 1.6
    s[2:5, 17] = 1.2
    kept = lambda aim: np.isfinite(keep_aimed_piece(s, aim))  # noqa: E731
    # the box under the aim: 24 of the wall's 60 nodes, above a quarter: the box
    assert kept((3, 12)).sum() == 24 and kept((3, 12))[3, 12]
    # the leg under the aim (3 nodes): passed over for the largest piece, the wall
    assert kept((3, 17)).sum() == 60 and kept((3, 17))[0, 0]
    # no piece under the aim: the largest
    assert kept((0, 19)).sum() == 60
    # with no share asked, the aimed piece whatever its size
    assert np.isfinite(keep_aimed_piece(s, (3, 17), min_share=0.0)).sum() == 3


# --- a jump on a wall seen obliquely; an oblique wall without one -----------------------


def oblique_scene(tilt_deg: float, step_m: float, edge_u: int) -> tuple[FloatArray, FloatArray]:
    """Depth frame (h, w) of a wall turned ``tilt_deg`` from facing the camera (its depth
    growing to the right, 2 m ahead on the axis), quantised; right of column ``edge_u``
    a parallel wall ``step_m`` behind it (a door frame's end, a recess: the jump along
    the ray a corridor's side wall makes at a doorway). Also the normal in frame D."""
    t = np.radians(tilt_deg)
    normal = np.array([np.sin(t), 0.0, -np.cos(t)])
    rays = depth_rays()
    near = plane_depth(rays, normal, np.array([0.0, 0.0, 2.0]))
    far = plane_depth(rays, normal, np.array([0.0, 0.0, 2.0]) - step_m * normal)
    z = np.where(np.arange(D.width)[None, :] < edge_u, near, far)
    return quantised(z), normal


def test_jump_pixels_are_silhouettes_not_an_oblique_wall() -> None:
    """The depth image's jump pixels: along a box's silhouette (and only within 2 px of
    it), none on a quantised wall 78 deg from facing the camera (its depth steps every
    pixel or two)."""
    settings = DepthSettings()
    sensor = SensorModel.of(D)
    z, box = box_scene(0.0)
    jumps = clean_images(z, settings, True, Workspace(), sensor)[2]
    assert jumps is not None
    rays = depth_rays()
    x, y = rays[..., 0] * box[4], rays[..., 1] * box[4]
    px = box[4] / D.focal  # one pixel on the box's face (m)
    inside = (x >= box[0] - 3 * px) & (x <= box[1] + 3 * px) & (np.abs(y) <= 0.2 + 3 * px)
    core = (x >= box[0] + 3 * px) & (x <= box[1] - 3 * px) & (np.abs(y) <= 0.2 - 3 * px)
    near_edge = inside & ~core
    assert jumps.sum() > 0 and np.all(near_edge[jumps])
    rows = np.flatnonzero(np.abs(y[:, 0]) < 0.15)  # every row across the box's sides
    assert jumps[rows].any(axis=1).all()
    z, _ = oblique_scene(78.0, 0.0, D.width)
    jumps = clean_images(z, settings, True, Workspace(), sensor)[2]
    assert jumps is not None and not jumps.any()


def test_a_jump_the_lattice_slope_explains_is_cut_where_the_image_jumps() -> None:
    """Nodes on a wall seen obliquely (0.3 m deeper at each node) and 0.6 m more across
    one column: the lattice's own rule reads the jump as the slope; the depth image,
    sharp there, cuts it, dropping the farther nodes only."""
    shape = (21, 21)
    s = 2.0 + 0.1 * np.arange(shape[1])[None, :].repeat(shape[0], axis=0)
    s[:, 12:] += 0.6
    sensor = SensorModel.of(D)
    settings = DepthSettings()
    _, blocked = cut_lattice(s, sensor, settings.jump_sigmas, 6.0)
    assert not blocked.any()  # (a slope allowance that reads the jump as slope)
    rays = SurfaceEstimator(CAL).rays(shape)
    R, t = CAL.T_P_D[:3, :3], CAL.T_P_D[:3, 3]
    uv = ((rays * s[..., None] - t) @ R) @ D.K.T
    u_mid = 0.5 * (uv[:, 11, 0] / uv[:, 11, 2] + uv[:, 12, 0] / uv[:, 12, 2])
    jumps = np.zeros((D.height, D.width), bool)
    for u in np.rint(u_mid).astype(int):
        jumps[:, u - 1 : u + 2] = True
    got, dropped = cut_at_jumps(s, rays, CAL, jumps, sensor, settings.jump_sigmas)
    assert dropped[:, 12].all() and dropped.sum() == shape[0]
    assert np.isnan(got[:, 12]).all() and np.isfinite(np.delete(got, 12, axis=1)).all()
    # no jump in the image: nothing cut
    none = cut_at_jumps(s, rays, CAL, np.zeros_like(jumps), sensor, settings.jump_sigmas)[1]
    assert not none.any()


@pytest.mark.parametrize("tilt_deg", [70.0, 78.0])
def test_a_steep_continuous_wall_seen_obliquely_is_not_cut(tilt_deg: float) -> None:
    """The hard case for a cut: a quantised wall 70-78 deg from facing the camera (its
    depth steps every pixel or two, nodes 10-20 cm apart in depth) is one surface: every
    node the pipeline without cuts finds is kept."""
    z, _ = oblique_scene(tilt_deg, 0.0, D.width)
    shape = (21, 21)
    cut = SurfaceEstimator(CAL).estimate(z, shape).surface.points[..., 2]
    whole = SurfaceEstimator(CAL, DepthSettings(cut=False)).estimate(z, shape).surface.points
    assert np.isfinite(whole[..., 2]).mean() > 0.5  # (the far end beyond 6 m)
    assert np.array_equal(np.isfinite(cut), np.isfinite(whole[..., 2]))


# --- a crease with a hole beside it is one surface --------------------------------------


def corner_scene(roll_deg: float, concave: bool, side: int, off_nodes: float) -> FloatArray:
    """Depth frame (h, w) of two walls meeting at a crease through the point 2 m ahead
    (each 55 deg from facing the camera; a room's inside corner when ``concave``, a
    column's edge else), the crease rolled ``roll_deg`` from upright in the image,
    quantised, with a round hole (an untextured patch, 1.5 lattice nodes across) whose
    centre is ``off_nodes`` lattice nodes to the ``side`` (+1 / -1) of the crease."""
    r, a = np.radians(roll_deg), np.radians(55.0)
    perp = np.array([np.cos(r), -np.sin(r), 0.0])  # across the crease, in the image
    ez, p0 = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 2.0])
    rays = depth_rays()
    z1 = plane_depth(rays, np.sin(a) * perp - np.cos(a) * ez, p0)
    z2 = plane_depth(rays, -np.sin(a) * perp - np.cos(a) * ez, p0)
    z = np.fmin(z1, z2) if concave else np.fmax(z1, z2)
    # the lattice's node spacing in the depth image across the crease (a 21 x 21
    # lattice over the projector's frame, seen from the depth camera 2 m ahead)
    node = np.hypot(NODE_PX[0] * perp[0], NODE_PX[1] * perp[1])
    v, u = np.mgrid[0 : D.height, 0 : D.width].astype(np.float64)
    du, dv = u - D.K[0, 2], v - D.K[1, 2]  # the crease's line passes the image centre
    c = side * off_nodes * node * perp
    z[(du - c[0]) ** 2 + (dv - c[1]) ** 2 <= (0.75 * node) ** 2] = np.nan
    return quantised(z)


NODE_PX = (15.8, 9.9)  # a 21 x 21 lattice's spacing in the depth image (u, v), in px


@pytest.mark.parametrize("roll_deg", [0.0, 35.0, 90.0])
@pytest.mark.parametrize("concave", [True, False])
def test_a_crease_beside_a_hole_is_not_cut(roll_deg: float, concave: bool) -> None:
    """A wall corner's crease is continuous in depth, only its slope turns: with a hole
    beside it (where the neighbouring pair the cut rule reads the slope from is
    unknown), no node of it is cut. Once, the crease's nodes were dropped (a slit the
    content avoided). Every node the pipeline without cuts finds is kept, for holes at
    sub-node offsets either side of creases upright, slanted and level."""
    shape = (21, 21)
    for side in (-1, 1):
        for off_nodes in (2.0, 2.5):
            z = corner_scene(roll_deg, concave, side, off_nodes)
            cut = SurfaceEstimator(CAL).estimate(z, shape).surface.points[..., 2]
            whole = SurfaceEstimator(CAL, DepthSettings(cut=False)).estimate(z, shape)
            lost = np.isfinite(whole.surface.points[..., 2]) & ~np.isfinite(cut)
            assert not lost.any(), (side, off_nodes, np.argwhere(lost))


# --- a step with a hole beside it stays cut ----------------------------------------------


def step_scene(
    z0: float, tilt_deg: float, roll_deg: float, side: int, off_nodes: float
) -> tuple[FloatArray, FloatArray, float]:
    """Depth frame (h, w) of a wall through the point ``z0`` ahead, turned ``tilt_deg``
    about the vertical from facing the camera, whose part on one side of a line through
    the image centre (rolled ``roll_deg`` from upright) stands back along the ray there
    by 1.1x the cut's noise limit (``jump_sigmas`` sigma at the far depth), quantised,
    with a round hole (1.5 lattice nodes across) ``off_nodes`` nodes to the ``side`` of
    the step; the wall's normal (frame D) and the far part's depth at the centre."""
    sensor, sigmas = SensorModel.of(D), DepthSettings().jump_sigmas
    far = z0
    for _ in range(20):  # far = z0 + 1.1 sigmas sigma(far)
        far = z0 + 1.1 * sigmas * float(sensor.sigma_m(far))
    t, r = np.radians(tilt_deg), np.radians(roll_deg)
    normal = np.array([np.sin(t), 0.0, -np.cos(t)])
    rays = depth_rays()
    perp = np.array([np.cos(r), -np.sin(r)])  # across the step, in the image
    v, u = np.mgrid[0 : D.height, 0 : D.width].astype(np.float64)
    du, dv = u - D.K[0, 2], v - D.K[1, 2]
    z = np.where(
        du * perp[0] + dv * perp[1] > 0,
        plane_depth(rays, normal, np.array([0.0, 0.0, far])),
        plane_depth(rays, normal, np.array([0.0, 0.0, z0])),
    )
    node = np.hypot(NODE_PX[0] * perp[0], NODE_PX[1] * perp[1])
    c = side * off_nodes * node * perp
    z[(du - c[0]) ** 2 + (dv - c[1]) ** 2 <= (0.75 * node) ** 2] = np.nan
    return quantised(z), normal, far


@pytest.mark.parametrize("z0, tilt_deg", [(2.5, 0.0), (5.0, 0.0), (5.0, 60.0)])
@pytest.mark.parametrize("roll_deg", [0.0, 90.0])
def test_a_step_beside_a_hole_stays_cut(z0: float, tilt_deg: float, roll_deg: float) -> None:
    """A step just beyond the noise limit (1.1x) is cut with a hole beside it, on either
    side, as it is without one: the slope measured across the hole (the wall's own) does
    not explain it. At 5 m the far part is at 5.7 m (the step 0.69 m), within the
    sensor's range. Each node is told to one of the two planes by its distance to them
    (the truth, in frame D): no lattice edge joins the two, and none lies between them
    (a curtain: a quarter of the step off both, against the quantisation's ~3 %)."""
    shape = (21, 21)
    R, t = CAL.T_P_D[:3, :3], CAL.T_P_D[:3, 3]
    for side in (-1, 1):
        for off_nodes in (1.0, 2.0):
            z, normal, far = step_scene(z0, tilt_deg, roll_deg, side, off_nodes)
            pts = SurfaceEstimator(CAL).estimate(z, shape).surface.points.astype(np.float64)
            x = (pts - t) @ R  # frame D
            near_off = np.abs(x @ normal - normal[2] * z0)
            far_off = np.abs(x @ normal - normal[2] * far)
            known = np.isfinite(near_off)
            assert known.sum() > 0.3 * known.size
            gap = abs(normal[2]) * (far - z0)
            assert np.fmin(near_off, far_off)[known].max() < 0.25 * gap, (side, off_nodes)
            on_far = far_off < near_off
            for a, b in (
                ((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
            ):
                joins = known[a] & known[b] & (on_far[a] != on_far[b])
                assert not joins.any(), (side, off_nodes, np.argwhere(joins))
