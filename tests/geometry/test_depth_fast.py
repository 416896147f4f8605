"""The fast depth -> surface path against the straightforward one it replaced.

``ref_*`` below are the functions of ``adaproj_edge/geometry/depth.py`` (now a package) as
they were before the speed-up (commit aeace31), unchanged but for their names: the side-window
fit on the whole (supersampled) lattice with ``cv2.filter2D`` and two batched solves,
and the float64 image stages. The fast code evaluates the fits only at the nodes that
are kept, through separable banded sums, and must give the same numbers up to
floating-point order. ``tools/bench_depth.py`` times both.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth import estimate, fits, images, lattice, rays
from adaproj_edge.geometry.depth.estimate import SurfaceEstimate
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.depth.workspace import Workspace
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface

# --- the reference: depth.py before the speed-up -----------------------------------


def ref_lattice_uv(projector: Projector, shape: tuple[int, int]) -> FloatArray:
    """Projector pixel coordinates (rows, cols, 2) of a lattice whose corners are the
    corner pixel centres (the Surface convention)."""
    rows, cols = shape
    xs = np.linspace(0.0, projector.width - 1.0, cols)
    ys = np.linspace(0.0, projector.height - 1.0, rows)
    return np.stack(np.meshgrid(xs, ys), axis=-1)


def ref_depth_sigma(
    z: FloatArray, calibration: Calibration, disparity_sigma_px: float
) -> FloatArray:
    """Stereo depth noise (m) at depth ``z``: z^2 / (f B) * sigma_disparity."""
    d = calibration.depth
    return z * z / (d.focal * d.baseline_m) * disparity_sigma_px


def ref_clean_depth(depth_m: FloatArray, settings: DepthSettings) -> FloatArray:
    """Range check and speckle rejection; (h, w) metres with NaN where invalid."""
    z = np.asarray(depth_m, dtype=np.float64).copy()
    with np.errstate(invalid="ignore"):
        z[~((z >= settings.min_depth_m) & (z <= settings.max_depth_m))] = np.nan
    z32 = np.nan_to_num(z, nan=0.0).astype(np.float32)
    med = cv2.medianBlur(z32, 5).astype(np.float64)
    with np.errstate(invalid="ignore"):
        z[np.abs(z - med) > settings.speckle_rel * z] = np.nan
    return z


def ref_smooth_depth(z: FloatArray, sigma_px: float) -> tuple[FloatArray, FloatArray]:
    """Normalised-convolution smoothing: (smoothed z, support), both (h, w)."""
    m = np.isfinite(z).astype(np.float32)
    zz = np.where(m > 0, z, 0.0).astype(np.float32)
    num = cv2.GaussianBlur(zz, (0, 0), sigma_px, borderType=cv2.BORDER_CONSTANT)
    den = cv2.GaussianBlur(m, (0, 0), sigma_px, borderType=cv2.BORDER_CONSTANT)
    with np.errstate(invalid="ignore", divide="ignore"):
        zs = np.where(den > 1e-3, num / den, np.nan)
    return zs.astype(np.float64), den.astype(np.float64)


def ref_sample(img: NDArray[np.float32], uv: FloatArray) -> FloatArray:
    """Bilinear sample of ``img`` (h, w) at ``uv`` (..., 2); 0 outside."""
    mx = uv[..., 0].astype(np.float32)
    my = uv[..., 1].astype(np.float32)
    out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out.astype(np.float64)


def ref_intersect_rays(
    dirs_p: FloatArray,
    zs: FloatArray,
    support: FloatArray,
    calibration: Calibration,
    settings: DepthSettings,
) -> tuple[FloatArray, FloatArray]:
    """Ray parameter ``s`` (...,) where rays ``s * dirs_p`` (..., 3) in frame P meet the
    smoothed depth surface ``zs`` (h, w), and the support there; NaN where they do not.
    """
    T = calibration.T_P_D
    R, t = T[:3, :3], T[:3, 3]
    a = dirs_p @ R  # R^T d: ray direction in D
    b = -R.T @ t  # projector centre in D
    K = calibration.depth.K
    valid = np.isfinite(zs) & (support >= settings.min_support)
    num = np.where(valid, zs * support, 0.0).astype(np.float32)
    wgt = np.where(valid, support, 0.0).astype(np.float32)
    sup = support.astype(np.float32)
    good = zs[valid]
    s = np.full(dirs_p.shape[:-1], float(np.median(good)) if good.size else 1.0)
    z_meas = np.full_like(s, np.nan)
    for _ in range(settings.iterations):
        x = s[..., None] * a + b
        with np.errstate(invalid="ignore", divide="ignore"):
            uv = (x @ K.T)[..., :2] / x[..., 2:3]
        uv = np.nan_to_num(uv, nan=-10.0, posinf=-10.0, neginf=-10.0)
        w = ref_sample(wgt, uv)
        with np.errstate(invalid="ignore", divide="ignore"):
            z_meas = np.where(w > 1e-3, ref_sample(num, uv) / w, np.nan)
            s_new = (z_meas - b[2]) / a[..., 2]
        s = np.where(np.isfinite(s_new) & (s_new > 0), s_new, s)
    x = s[..., None] * a + b
    with np.errstate(invalid="ignore", divide="ignore"):
        uv = (x @ K.T)[..., :2] / x[..., 2:3]
    uv = np.nan_to_num(uv, nan=-10.0, posinf=-10.0, neginf=-10.0)
    sup_at = ref_sample(sup, uv)
    mask_at = ref_sample(valid.astype(np.float32), uv)
    with np.errstate(invalid="ignore"):
        residual = np.abs(x[..., 2] - z_meas)
        ok = (
            np.isfinite(z_meas)
            & (mask_at > 0.5)
            & (residual < 0.002 + 0.01 * s)
            & (s > settings.min_depth_m)
        )
    return np.where(ok, s, np.nan), np.where(ok, sup_at, 0.0)


def ref_side_window_fit(
    s: FloatArray, sigma_nodes: float, min_weight: float = 3.0, switch: float = 3.0
) -> tuple[FloatArray, FloatArray]:
    """Local quadratic regression of inverse depth over the lattice (rows, cols), in
    side windows so that creases and steps stay sharp.

    For each node a quadratic in the lattice coordinates is fitted to ``1 / s`` of its
    neighbours (Gaussian weights of ``sigma_nodes``) in five windows: the whole
    neighbourhood and its left, right, upper and lower halves. The whole window is
    used unless one half fits ``switch`` times better (the node is next to a crease,
    where only the half on its own side belongs to its face). Inverse depth is affine
    in image coordinates on a plane, so walls stay exact; quadrics (spheres,
    cylinders, bowls) are followed up to third-order terms.

    Returns
    -------
    q : (rows, cols) fitted inverse depth, NaN where there is no fit
    rss : (rows, cols) weighted mean squared residual of the chosen window
    """
    r = int(np.ceil(2 * sigma_nodes))
    valid = np.isfinite(s) & (s > 0)
    q = np.where(valid, 1.0 / np.where(valid, s, 1.0), 0.0)
    m = valid.astype(np.float64)
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    g = np.exp(-(dx * dx + dy * dy) / (2 * sigma_nodes**2))
    x, y = dx / r, dy / r
    halves = [np.ones_like(g), dx <= 0, dx >= 0, dy <= 0, dy >= 0]  # whole, left, right, up, down
    powers = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]  # the quadratic basis x^a y^b

    def corr(img: FloatArray, kernel: FloatArray) -> FloatArray:
        # sum over the window of kernel(offset) * img(node + offset), zeros outside
        out = cv2.filter2D(img, cv2.CV_64F, kernel, borderType=cv2.BORDER_CONSTANT)
        return np.asarray(out, dtype=np.float64)

    fits, rss, enough, var = [], [], [], []
    for half in halves:
        w = g * half
        wbar = float(np.sum(w * w) / np.sum(w))
        mom = {}
        for a1, b1 in powers:
            for a2, b2 in powers:
                key = (a1 + a2, b1 + b2)
                if key not in mom:
                    mom[key] = corr(m, w * x ** key[0] * y ** key[1])
        A = np.stack([np.stack([mom[(a1 + a2, b1 + b2)] for a2, b2 in powers], -1)
                      for a1, b1 in powers], -2)  # fmt: skip
        bq = np.stack([corr(m * q, w * x**a1 * y**b1) for a1, b1 in powers], -1)
        sqq = corr(m * q * q, w)
        ok = valid & (mom[(0, 0)] >= min_weight)
        A[~ok] = np.eye(6)
        bq[~ok] = 0.0
        coef = np.linalg.solve(A + 1e-9 * np.eye(6), bq[..., None])[..., 0]
        e0 = np.zeros(6)
        e0[0] = 1.0
        a00 = np.linalg.solve(A + 1e-9 * np.eye(6), np.broadcast_to(e0, bq.shape)[..., None])
        a00 = a00[..., 0, 0]
        # weighted residual sum of squares from the moments: S - 2 c.b + c^T A c
        res = sqq - 2 * np.sum(coef * bq, -1) + np.einsum("...i,...ij,...j->...", coef, A, coef)
        with np.errstate(invalid="ignore", divide="ignore"):
            rss.append(np.where(ok, np.maximum(res, 0.0) / mom[(0, 0)], np.inf))
        fits.append(coef[..., 0])
        enough.append(ok)
        var.append(rss[-1] * a00 * wbar)
    R = np.stack(rss)
    side = 1 + np.argmin(R[1:], axis=0)
    best_side = np.take_along_axis(R[1:], (side - 1)[None], axis=0)[0]
    choice = np.where(R[0] > switch * best_side, side, 0)
    ok_any = np.stack(enough)
    choice = np.where(
        ok_any[0], choice, np.where(ok_any.any(axis=0), np.argmax(ok_any, axis=0), -1)
    )
    qf = np.take_along_axis(np.stack(fits), np.maximum(choice, 0)[None], axis=0)[0]
    vf = np.take_along_axis(np.stack(var), np.maximum(choice, 0)[None], axis=0)[0]
    good = valid & (choice >= 0) & (qf > 0)
    return np.where(good, qf, np.nan), np.where(good, vf, np.inf)


def ref_smooth_lattice(
    s: FloatArray,
    sigma_nodes: float,
    scales: tuple[float, ...] = (1.0,),
    accept: float = 1.5,
) -> FloatArray:
    """Side-window quadratic smoothing (:func:`ref_side_window_fit`) at ``sigma_nodes``
    times each of ``scales`` (increasing): a node takes the largest scale whose fit is
    still about as good (residual at most ``accept`` times) as the scale below it, so
    flat and gently curved parts get the most smoothing and tighter shapes keep
    their detail. Unknown nodes stay unknown; nodes without a fit keep their value.
    """
    if sigma_nodes < 0.5:
        return s
    valid = np.isfinite(s) & (s > 0)
    q, var = ref_side_window_fit(s, sigma_nodes * scales[0])
    for k in scales[1:]:
        q2, var2 = ref_side_window_fit(s, sigma_nodes * k)
        with np.errstate(invalid="ignore"):
            take = np.isfinite(q2) & (np.abs(q2 - q) <= accept * np.sqrt(var))
        q = np.where(take, q2, q)
        var = np.where(take, var2, var)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(valid & np.isfinite(q) & (q > 0), 1.0 / q, np.where(valid, s, np.nan))


def ref_node_spacing_m(projector: Projector, shape: tuple[int, int], depth_m: float) -> float:
    """Distance between neighbouring lattice nodes on a surface ``depth_m`` away."""
    rows, cols = shape
    step_px = min(
        (projector.width - 1) / max(cols - 1, 1), (projector.height - 1) / max(rows - 1, 1)
    )
    return depth_m * step_px / float(projector.K[0, 0])


def ref_reject_spikes(s: FloatArray, rel: float) -> FloatArray:
    """Drop nodes that stick out of their neighbours in every direction (rows, cols)."""
    p = np.pad(s, 1, constant_values=np.nan)
    c = p[1:-1, 1:-1]
    dev = []
    for (y0, x0), (y1, x1) in (
        ((0, 1), (2, 1)),
        ((1, 0), (1, 2)),
        ((0, 0), (2, 2)),
        ((0, 2), (2, 0)),
    ):
        a = p[y0 : y0 + c.shape[0], x0 : x0 + c.shape[1]]
        b = p[y1 : y1 + c.shape[0], x1 : x1 + c.shape[1]]
        dev.append(np.abs(c - (a + b) / 2))
    with np.errstate(invalid="ignore"):
        d = np.stack(dev)
        known = np.isfinite(d)
        spike = np.all(~known | (d > rel * c), axis=0) & (known.sum(axis=0) >= 3)
    out = s.copy()
    out[spike] = np.nan
    return out


def ref_fill_holes(s: FloatArray, max_nodes: int) -> tuple[FloatArray, BoolArray]:
    """Fill NaN regions of at most ``max_nodes`` nodes that do not touch the border.

    Harmonic fill (each filled node the mean of its neighbours). Returns the filled
    lattice and the mask of filled nodes.
    """
    hole = ~np.isfinite(s)
    labels, n = ndimage.label(hole)
    if n == 0:
        return s, np.zeros_like(hole)
    sizes = np.bincount(labels.ravel())
    border = np.unique(np.r_[labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    small = sizes <= max_nodes
    small[0] = False
    small[border] = False
    fill = small[labels]
    if not fill.any():
        return s, fill
    out = np.where(fill, np.nanmean(s), s)
    for _ in range(4 * max_nodes + 20):
        p = np.pad(out, 1, mode="edge")
        nb = np.stack([p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]])
        with np.errstate(invalid="ignore"):
            avg = np.nanmean(np.where(np.isfinite(nb), nb, np.nan), axis=0)
        out = np.where(fill, avg, out)
    return out, fill


def ref_node_confidence(
    points: FloatArray,
    support: FloatArray,
    filled: BoolArray,
    calibration: Calibration,
    settings: DepthSettings,
) -> NDArray[np.float32]:
    """Confidence (rows, cols) in [0, 1] of lattice ``points`` (rows, cols, 3)."""
    z = points[..., 2]
    valid = np.isfinite(z)
    c_support = np.clip(support / 0.8, 0.0, 1.0)
    sigma = ref_depth_sigma(np.where(valid, z, 0.0), calibration, settings.disparity_sigma_px)
    c_noise = np.exp(-((sigma / settings.sigma_ref_m) ** 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        dx = np.gradient(points, axis=1)
        dy = np.gradient(points, axis=0)
        n = np.cross(dx, dy)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        ray = points / np.linalg.norm(points, axis=-1, keepdims=True)
        cos = np.abs(np.sum(n * ray, axis=-1))
    c_angle = np.clip((np.nan_to_num(cos, nan=0.5) - 0.1) / 0.3, 0.0, 1.0)
    c = np.where(filled, 0.5, c_support) * c_noise * c_angle
    return np.where(valid, c, 0.0).astype(np.float32)


def ref_estimate_surface(
    depth_m: FloatArray,
    calibration: Calibration,
    shape: tuple[int, int] = (21, 21),
    settings: DepthSettings | None = None,
) -> SurfaceEstimate:
    """The Surface at a (rows, cols) lattice of projector rays from one depth frame.

    Parameters
    ----------
    depth_m : (h, w) float array
        Depth in metres in frame D (z along the optical axis), NaN or 0 = invalid.
    calibration : Calibration
        Depth model, projector and ``T_P_D``.
    shape : (rows, cols)
        Lattice size: the warp grid's vertex count (e.g. (21, 21) for a 20x20 grid),
        or a fine lattice for a dense surface (see :func:`dense_shape`).
    """
    settings = settings or DepthSettings()
    z = np.asarray(depth_m, dtype=np.float64)
    if z.shape != (calibration.depth.height, calibration.depth.width):
        z = cv2.resize(
            np.nan_to_num(z, nan=0.0).astype(np.float32),
            (calibration.depth.width, calibration.depth.height),
            interpolation=cv2.INTER_NEAREST,
        ).astype(np.float64)
    z = np.where(z > 0, z, np.nan)
    zs, support = ref_smooth_depth(ref_clean_depth(z, settings), settings.smooth_sigma_px)
    p = calibration.projector
    dirs = p.rays(ref_lattice_uv(p, shape))
    k = ref_supersampling(p, shape, zs, settings)
    fine = ((shape[0] - 1) * k + 1, (shape[1] - 1) * k + 1)
    s, sup = ref_intersect_rays(p.rays(ref_lattice_uv(p, fine)), zs, support, calibration, settings)
    s = ref_reject_spikes(s, settings.spike_rel)
    if np.isfinite(s).any():
        spacing = ref_node_spacing_m(p, fine, float(np.nanmedian(s)))
        sigma = min(settings.smooth_m / spacing, settings.smooth_max_nodes)
        s = ref_smooth_lattice(s, sigma, settings.smooth_scales, settings.smooth_accept)
    s, sup = s[::k, ::k], sup[::k, ::k]
    s, filled = ref_fill_holes(s, settings.max_hole_nodes)
    points = dirs * s[..., None]
    conf = ref_node_confidence(points, np.where(filled, 0.5, sup), filled, calibration, settings)
    surface = Surface(points.astype(np.float32), p, {"source": "depth"})
    est = SurfaceEstimate(surface, conf, filled & np.isfinite(s))
    return replace(est, surface=replace(surface, meta={"source": "depth", **est.summary()}))


def ref_supersampling(
    projector: Projector, shape: tuple[int, int], zs: FloatArray, settings: DepthSettings
) -> int:
    """How many times finer than ``shape`` to sample, so that nodes are at most
    ``smooth_m / 2`` apart on the surface (1 for fine lattices, at most 4)."""
    good = zs[np.isfinite(zs)]
    z = float(np.median(good)) if good.size else 1.5
    k = np.ceil(ref_node_spacing_m(projector, shape, z) / (settings.smooth_m / 2))
    return int(np.clip(k, 1, settings.max_supersample))


def ref_lattice_depths(
    depth_m: FloatArray, calibration: Calibration, shape: tuple[int, int], settings: DepthSettings
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """:func:`ref_estimate_surface` up to the filled lattice (depth along each ray,
    support, filled), as ``SurfaceEstimator.lattice_depths``."""
    z = np.asarray(depth_m, dtype=np.float64)
    z = np.where(z > 0, z, np.nan)
    zs, support = ref_smooth_depth(ref_clean_depth(z, settings), settings.smooth_sigma_px)
    p = calibration.projector
    k = ref_supersampling(p, shape, zs, settings)
    fine = ((shape[0] - 1) * k + 1, (shape[1] - 1) * k + 1)
    s, sup = ref_intersect_rays(p.rays(ref_lattice_uv(p, fine)), zs, support, calibration, settings)
    s = ref_reject_spikes(s, settings.spike_rel)
    if np.isfinite(s).any():
        spacing = ref_node_spacing_m(p, fine, float(np.nanmedian(s)))
        sigma = min(settings.smooth_m / spacing, settings.smooth_max_nodes)
        s = ref_smooth_lattice(s, sigma, settings.smooth_scales, settings.smooth_accept)
    s, sup = s[::k, ::k], sup[::k, ::k]
    s, filled = ref_fill_holes(s, settings.max_hole_nodes)
    return s, sup, filled


# --- the fast code against it --------------------------------------------------------

# the reference predates the sensor model's step floor in the smoothing and the cuts at
# silhouettes (tested against ground truth in test_depth_sensor.py): compared without
OLD = DepthSettings(step_floor=0.0, cut=False)

SESSIONS = ("cylinder", "corner", "sphere")
# the fits are small least-squares solves done in another order than the reference's
# (and by other BLAS builds on other CPUs): they agree to about cond(A) x eps, seen up
# to 3.4e-9 relative; 1e-6 leaves a wide margin and still catches any wrong term
RTOL = 1e-6
# the points are those depths times unit rays, stored as float32: one more rounding
F32_RTOL = RTOL + float(np.finfo(np.float32).eps)
# a few roundings of a float32 computation
F32_ULPS = 4 * float(np.finfo(np.float32).eps)
# a node's confidence comes from the normal of finite differences of the points (nodes
# a few cm apart at 1-2 m), which magnifies their relative differences ~100x; in [0, 1]
CONF_ATOL = 1e-4


@cache
def recorded(name: str) -> tuple[Calibration, tuple[FloatArray, ...]]:
    from adaproj_edge.session.reader import read_session

    session = read_session(f"tests/fixtures/sessions/{name}.mcap")
    return session.calibration, tuple(rec.metres() for rec in session.depth)


def assert_same(new: FloatArray, ref: FloatArray, rtol: float = RTOL, atol: float = 0.0) -> None:
    """Same shape and unknowns, values equal up to ``rtol`` (floating-point order)."""
    assert new.shape == ref.shape
    np.testing.assert_array_equal(np.isnan(new), np.isnan(ref))
    np.testing.assert_array_equal(np.isinf(new), np.isinf(ref))
    fin = np.isfinite(ref)
    np.testing.assert_allclose(new[fin], ref[fin], rtol=rtol, atol=atol)


def assert_same_meta(new: dict[str, Any], ref: dict[str, Any]) -> None:
    """The estimates' summaries: counts and decisions exactly; the mean confidence
    (rounded to 4 places) within :data:`CONF_ATOL` and one rounding step."""
    ref = {k: v for k, v in ref.items() if k != "frames"}  # the estimate's own field now
    assert new.keys() == ref.keys()
    for key in new:
        if key == "confidence":
            assert abs(new[key] - ref[key]) <= CONF_ATOL + 1e-4
        else:
            assert new[key] == ref[key], key


def test_sessions_are_there() -> None:
    for name in SESSIONS:
        _, frames = recorded(name)
        assert len(frames) >= 10 and frames[0].shape == (400, 640)


# the recorded frames have the sensor's holes (untextured patches): the reference's
# fill_holes warns when a node of a large one has no known neighbour (it is not filled)
@pytest.mark.filterwarnings("ignore:Mean of empty slice:RuntimeWarning")
@pytest.mark.parametrize("name", SESSIONS)
def test_lattice_depths_match_the_reference_on_recorded_frames(name: str) -> None:
    calibration, frames = recorded(name)
    settings = OLD
    ks = set()
    for z in frames:
        s, sup, filled = estimate.SurfaceEstimator(calibration, settings).lattice_depths(
            z, (21, 21)
        )
        s_ref, sup_ref, filled_ref = ref_lattice_depths(z, calibration, (21, 21), settings)
        assert_same(s, s_ref)
        assert_same(sup, sup_ref)
        np.testing.assert_array_equal(filled, filled_ref)
        zs, _ = ref_smooth_depth(ref_clean_depth(np.where(z > 0, z, np.nan), settings), 0.7)
        ks.add(ref_supersampling(calibration.projector, (21, 21), zs, settings))
    assert np.isfinite(s).mean() > 0.5
    if name != "corner":
        assert max(ks) > 1  # the supersampled lattice is exercised


@pytest.mark.filterwarnings("ignore:Mean of empty slice:RuntimeWarning")  # (as above)
@pytest.mark.parametrize("name", SESSIONS)
def test_estimate_surface_matches_the_reference(name: str) -> None:
    calibration, frames = recorded(name)
    shapes = [(21, 21), (11, 16), lattice.dense_shape(calibration.projector, 16)]
    for i, z in enumerate(frames[::4]):
        shape = shapes[i % len(shapes)]
        est = estimate.estimate_surface(z, calibration, shape, OLD)
        ref = ref_estimate_surface(z, calibration, shape, OLD)
        # points are float32: equal up to the last bit of a float32
        assert_same(est.surface.points, ref.surface.points, rtol=F32_RTOL)
        np.testing.assert_allclose(est.confidence, ref.confidence, rtol=0, atol=CONF_ATOL)
        np.testing.assert_array_equal(est.filled, ref.filled)
        assert_same_meta(est.surface.meta, ref.surface.meta)


# fill_holes (unchanged) warns when a hole has no known neighbour yet; both sides do
@pytest.mark.filterwarnings("ignore:Mean of empty slice:RuntimeWarning")
def test_estimate_surface_on_synthetic_depth_matches_the_reference() -> None:
    calibration = Calibration.default()
    v, u = np.mgrid[0:400, 0:640].astype(np.float64)
    rng = np.random.default_rng(3)
    wall = 1.0 / (0.6 + 0.0002 * u - 0.0001 * v)
    corner = 1.6 - 0.002 * np.abs(u - 301.3)
    noisy = corner + rng.normal(scale=0.004, size=corner.shape)
    holes = noisy.copy()
    holes[100:140, 200:260] = np.nan
    holes[:, :30] = 0.0
    holes[rng.random(holes.shape) < 0.05] = 0.0
    far = np.full((400, 640), 5.9)
    for z in (wall, corner, noisy, holes, far, np.zeros((400, 640)), holes[::2, ::2]):
        for shape in ((21, 21), (9, 13)):
            est = estimate.estimate_surface(z, calibration, shape, OLD)
            ref = ref_estimate_surface(z, calibration, shape, OLD)
            assert_same(est.surface.points, ref.surface.points, rtol=F32_RTOL)
            np.testing.assert_array_equal(est.filled, ref.filled)
            np.testing.assert_allclose(est.confidence, ref.confidence, rtol=0, atol=CONF_ATOL)


def test_image_stages_match_the_reference() -> None:
    calibration, frames = recorded("cylinder")
    settings = DepthSettings()
    p = calibration.projector
    dirs = p.rays(ref_lattice_uv(p, (41, 41)))
    for z in frames[::5]:
        z = np.where(z > 0, z, np.nan)
        # the depths kept are the input's own values (exact medians, comparisons): exact
        clean = images.clean_depth(z, settings)
        np.testing.assert_array_equal(clean, ref_clean_depth(z, settings))
        # float32 blurs and their quotient: a couple of float32 roundings
        zs, sup = images.smooth_depth(clean, 0.7)
        zs_ref, sup_ref = ref_smooth_depth(clean, 0.7)
        assert_same(zs, zs_ref, rtol=F32_ULPS)
        assert_same(sup, sup_ref, rtol=F32_ULPS, atol=F32_ULPS)  # support: in [0, 1]
        # the rays' positions in the image go to float32 maps for the sampling: a last
        # bit of a position may move a sample by a float32 step, then the iteration's
        # own rounding; RTOL (a mm at 1 m would be 1e-3) still catches any wrong term
        s, s_sup = rays.intersect_rays(dirs, zs, sup, calibration, settings)
        s_ref, s_sup_ref = ref_intersect_rays(dirs, zs, sup, calibration, settings)
        assert_same(s, s_ref)
        assert_same(s_sup, s_sup_ref)
        assert lattice.supersampling(p, (21, 21), zs, settings) == ref_supersampling(
            p, (21, 21), zs, settings
        )


def synthetic_lattices(noise: bool) -> list[tuple[str, FloatArray]]:
    """Lattices with creases, NaN holes (inside, along the border, scattered), nodes
    that are not positive, too sparse for a fit, smaller than the window.

    Without noise, which window or scale a node takes is decided by rounding where the
    fits agree to ~1e-7 (the reference itself moves that much when ``s`` is perturbed
    by 1e-15); all are compared to :data:`RTOL`.
    """
    rows, cols = 45, 61
    v, u = np.mgrid[0:rows, 0:cols].astype(np.float64)
    rng = np.random.default_rng(7)
    plane = 1.0 / (0.6 + 0.002 * u - 0.001 * v)
    crease = 1.5 - 0.01 * np.abs(u - 30.4) + 0.004 * np.abs(v - 20.7)
    dome = plane + 0.05 * np.exp(-((u - 30) ** 2 + (v - 20) ** 2) / 8.0)
    if not noise:
        return [("plane", plane), ("crease", crease), ("dome", dome)]
    noisy = crease + rng.normal(scale=0.003, size=crease.shape)
    holes = noisy.copy()
    holes[10:14, 10:16] = np.nan  # a hole
    holes[:, :3] = np.nan  # along the border
    holes[rng.random(holes.shape) < 0.08] = np.nan  # scattered
    holes[30:, 40:] = -1.0  # not positive: unknown as well
    sparse = np.where(rng.random(plane.shape) < 0.3, noisy, np.nan)  # too few for a fit
    return [
        ("noisy crease", noisy),
        ("noisy plane", plane + rng.normal(scale=0.002, size=plane.shape)),
        ("noisy dome", dome + rng.normal(scale=0.002, size=plane.shape)),
        ("holes", holes),
        ("sparse", sparse),
        ("small", noisy[:7, :9]),
        ("nothing", np.full((12, 10), np.nan)),
    ]


@cache
def settled_reference(
    noise: bool, index: int, sigma: float, scales: tuple[float, ...]
) -> tuple[FloatArray, BoolArray]:
    """:func:`ref_smooth_lattice` of the ``index``-th synthetic lattice, and the nodes
    whose value rounding does not decide.

    On the noisy lattices, a node whose fit at some scale leaves nothing but rounding
    (a residual below 1e-6 of the inverse depth; the noise leaves ~1e-3) has no more
    neighbours than unknowns (the sparse lattice): its window and scale are chosen by
    comparing residuals made of rounding, so by the CPU and the BLAS build. The
    noise-free lattices fit exactly everywhere, and there the windows agree (see
    :func:`synthetic_lattices`): every node is compared.
    """
    s = synthetic_lattices(noise)[index][1]
    settled = np.ones(s.shape, dtype=bool)
    if noise:
        for k in scales:
            q, var = ref_side_window_fit(s, sigma * k)
            with np.errstate(invalid="ignore"):
                settled &= ~(np.isfinite(q) & (var <= (1e-6 * q) ** 2))
    return ref_smooth_lattice(s, sigma, scales, 4.0), settled


@pytest.mark.parametrize("step", [1, 2, 3, 4])
@pytest.mark.parametrize("noise", [True, False])
def test_smooth_lattice_at_kept_nodes_matches_the_reference(step: int, noise: bool) -> None:
    for index, (name, s) in enumerate(synthetic_lattices(noise)):
        for sigma, scales in ((0.8, (1.0,)), (1.7, (1.0, 2.0, 4.0)), (3.0, (1.0, 2.0, 4.0))):
            new = fits.smooth_lattice(s, sigma, scales, 4.0, step=step)
            ref, settled = settled_reference(noise, index, sigma, scales)
            ref, settled = ref[::step, ::step], settled[::step, ::step]
            assert settled.mean() > 0.97, (name, sigma)  # the sparse one: 14 of 797 fitted
            try:
                assert_same(np.where(settled, new, ref), ref, rtol=RTOL)
            except AssertionError as e:
                raise AssertionError(f"{name} sigma={sigma} step={step}") from e


@pytest.mark.parametrize("step", [1, 3])
def test_side_window_fit_matches_the_reference(step: int) -> None:
    for _, s in synthetic_lattices(noise=True):
        for sigma in (0.6, 2.0, 5.0):
            q, rss = fits.side_window_fit(s, sigma, step=step)
            q_ref, rss_ref = ref_side_window_fit(s, sigma)
            assert_same(q, q_ref[::step, ::step])
            # a difference of sums of up to ~10^3 squares of depths ~2 m: rounding of
            # ~eps x 10^3 x 4 ~ 1e-12 in absolute terms, whatever the order (an exact
            # fit leaves that instead of 0); a wrong term is off by far more than 1e-9
            assert_same(rss, rss_ref[::step, ::step], rtol=RTOL, atol=1e-9)


def test_large_lattice_uses_strided_windows_and_matches() -> None:
    # the lattice much larger than the window: the sums over strided windows
    rng = np.random.default_rng(11)
    v, u = np.mgrid[0:90, 0:140].astype(np.float64)
    s = 1.4 + 0.002 * u + 0.004 * np.abs(v - 40.5) + rng.normal(scale=0.002, size=u.shape)
    s[20:30, 50:70] = np.nan
    for step in (1, 2):
        new = fits.smooth_lattice(s, 1.5, (1.0, 2.0, 4.0), 4.0, step=step)
        assert_same(new, ref_smooth_lattice(s, 1.5, (1.0, 2.0, 4.0), 4.0)[::step, ::step])


def test_window_sums_are_the_correlation() -> None:
    rng = np.random.default_rng(5)
    img = rng.normal(size=(37, 50))
    kern = rng.normal(size=(4, 9))
    for step in (1, 2, 3):
        for a in (img, img[:12]):  # strided windows, banded matrix
            out = fits._window_sums(a, kern, step)
            for i in range(4):
                full = cv2.filter2D(a, cv2.CV_64F, kern[i][:, None], borderType=cv2.BORDER_CONSTANT)
                # sums of 9 products of N(0, 1) numbers: rounding below 9 eps x sum|a k|
                # ~ 1e-14 in any order, so 1e-12 holds on any CPU
                np.testing.assert_allclose(out[i], full[::step], rtol=1e-12, atol=1e-12)


def test_medians_are_exact() -> None:
    rng = np.random.default_rng(9)
    for n in (1, 2, 3, 10, 8193, 8194, 50001, 256000):
        base = (rng.random(n) * 3 + 0.4).astype(np.float32)
        for values in (base, np.full(n, 1.5, np.float32), np.sort(base), np.round(base, 1)):
            outer = rng.random(n) < 0.8
            for inner in (outer & (rng.random(n) < 0.9), outer & (rng.random(n) < 0.2), ~outer):
                inner &= outer
                got = images._medians(values.astype(np.float32), inner, outer, Workspace())
                want = tuple(
                    float(np.median(values[w].astype(np.float64))) if w.any() else None
                    for w in (inner, outer)
                )
                assert got == want


def test_smooth_lattice_keeps_its_old_contract() -> None:
    s = synthetic_lattices(noise=False)[0][1]
    assert fits.smooth_lattice(s, 0.3) is s  # too little to smooth
    assert fits.smooth_lattice(s, 0.3, step=2).shape == (23, 31)
    assert fits.smooth_lattice(s, 2.0, step=4).shape == (12, 16)
