"""Depth frame + calibration -> the Surface the warp engine needs.

Steps (:func:`estimate_surface`):

1. depth outside the working range, and pixels far from their 5x5 median (speckle),
   are dropped;
2. the depth image is smoothed by normalised convolution (a Gaussian over valid
   pixels only), which also gives each pixel its *support* (how much valid data is
   around it);
3. each lattice node's projector ray is intersected with that smoothed depth surface:
   the point ``s d`` on the ray is moved into frame D, projected into the depth image,
   and ``s`` updated until the depth it predicts matches the depth measured there (the
   P-D baseline is a few centimetres, so this converges in a few steps). This
   back-projects, transforms to frame P and resamples in projector space at once,
   and keeps creases sharp;
4. this is done on a lattice fine enough to use the data between coarse nodes
   (:func:`supersampling`); isolated spikes are rejected, the surface is smoothed by
   local quadratic fits of inverse depth in side windows, which keep creases, at
   ``smooth_m`` and wider scales, each node taking the widest scale that agrees with
   the narrower ones (:func:`smooth_lattice`), and the requested lattice is taken
   from it; small holes (not touching the frame border) are filled from their
   neighbours;
5. every node gets a confidence in [0, 1] from support, the stereo noise expected at
   its depth (grows with z^2), the viewing angle, and whether it was filled.

:class:`SurfaceFilter` averages estimates over time while the device is still
(:func:`is_still` decides that from IMU samples). Grazing angles, holes and surfaces
out of range lower coverage and confidence; they never raise.
Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.projector import FloatArray, Projector
from adaproj_edge.geometry.surface import Surface

BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class DepthSettings:
    """Tuning of the depth -> surface pipeline (metres, pixels)."""

    min_depth_m: float = 0.35
    max_depth_m: float = 6.0
    speckle_rel: float = 0.03
    smooth_sigma_px: float = 0.7
    min_support: float = 0.35
    iterations: int = 8
    max_hole_nodes: int = 16
    disparity_sigma_px: float = 0.1
    sigma_ref_m: float = 0.02
    spike_rel: float = 0.02
    smooth_m: float = 0.06
    smooth_max_nodes: float = 3.0
    max_supersample: int = 4
    smooth_scales: tuple[float, ...] = (1.0, 2.0, 4.0)
    smooth_accept: float = 4.0


@dataclass(frozen=True)
class SurfaceEstimate:
    """A Surface lattice with per-node confidence.

    Attributes
    ----------
    surface : Surface
        Points (rows, cols, 3) in frame P, NaN where unknown.
    confidence : (rows, cols) float32
        In [0, 1]; 0 where there is no point.
    filled : (rows, cols) bool
        Nodes filled in from neighbours (a hole in the depth data).
    frames : int
        Depth frames averaged into this estimate.
    """

    surface: Surface
    confidence: NDArray[np.float32]
    filled: BoolArray
    frames: int = 1

    @property
    def coverage(self) -> float:
        """Fraction of lattice nodes with a point."""
        return self.surface.valid_fraction

    @property
    def mean_confidence(self) -> float:
        """Mean confidence over the whole lattice (unknown nodes count as 0)."""
        return float(np.mean(self.confidence))

    def summary(self) -> dict[str, float | int]:
        return {
            "coverage": round(self.coverage, 4),
            "confidence": round(self.mean_confidence, 4),
            "filled": int(self.filled.sum()),
            "frames": self.frames,
        }


def lattice_uv(projector: Projector, shape: tuple[int, int]) -> FloatArray:
    """Projector pixel coordinates (rows, cols, 2) of a lattice whose corners are the
    corner pixel centres (the Surface convention)."""
    rows, cols = shape
    xs = np.linspace(0.0, projector.width - 1.0, cols)
    ys = np.linspace(0.0, projector.height - 1.0, rows)
    return np.stack(np.meshgrid(xs, ys), axis=-1)


def depth_sigma(z: FloatArray, calibration: Calibration, disparity_sigma_px: float) -> FloatArray:
    """Stereo depth noise (m) at depth ``z``: z^2 / (f B) * sigma_disparity."""
    d = calibration.depth
    return z * z / (d.focal * d.baseline_m) * disparity_sigma_px


def clean_depth(depth_m: FloatArray, settings: DepthSettings) -> FloatArray:
    """Range check and speckle rejection; (h, w) metres with NaN where invalid."""
    z = np.asarray(depth_m, dtype=np.float64).copy()
    with np.errstate(invalid="ignore"):
        z[~((z >= settings.min_depth_m) & (z <= settings.max_depth_m))] = np.nan
    z32 = np.nan_to_num(z, nan=0.0).astype(np.float32)
    med = cv2.medianBlur(z32, 5).astype(np.float64)
    with np.errstate(invalid="ignore"):
        z[np.abs(z - med) > settings.speckle_rel * z] = np.nan
    return z


def smooth_depth(z: FloatArray, sigma_px: float) -> tuple[FloatArray, FloatArray]:
    """Normalised-convolution smoothing: (smoothed z, support), both (h, w)."""
    m = np.isfinite(z).astype(np.float32)
    zz = np.where(m > 0, z, 0.0).astype(np.float32)
    num = cv2.GaussianBlur(zz, (0, 0), sigma_px, borderType=cv2.BORDER_CONSTANT)
    den = cv2.GaussianBlur(m, (0, 0), sigma_px, borderType=cv2.BORDER_CONSTANT)
    with np.errstate(invalid="ignore", divide="ignore"):
        zs = np.where(den > 1e-3, num / den, np.nan)
    return zs.astype(np.float64), den.astype(np.float64)


def _sample(img: NDArray[np.float32], uv: FloatArray) -> FloatArray:
    """Bilinear sample of ``img`` (h, w) at ``uv`` (..., 2); 0 outside."""
    mx = uv[..., 0].astype(np.float32)
    my = uv[..., 1].astype(np.float32)
    out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out.astype(np.float64)


def intersect_rays(
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
        w = _sample(wgt, uv)
        with np.errstate(invalid="ignore", divide="ignore"):
            z_meas = np.where(w > 1e-3, _sample(num, uv) / w, np.nan)
            s_new = (z_meas - b[2]) / a[..., 2]
        s = np.where(np.isfinite(s_new) & (s_new > 0), s_new, s)
    x = s[..., None] * a + b
    with np.errstate(invalid="ignore", divide="ignore"):
        uv = (x @ K.T)[..., :2] / x[..., 2:3]
    uv = np.nan_to_num(uv, nan=-10.0, posinf=-10.0, neginf=-10.0)
    sup_at = _sample(sup, uv)
    mask_at = _sample(valid.astype(np.float32), uv)
    with np.errstate(invalid="ignore"):
        residual = np.abs(x[..., 2] - z_meas)
        ok = (
            np.isfinite(z_meas)
            & (mask_at > 0.5)
            & (residual < 0.002 + 0.01 * s)
            & (s > settings.min_depth_m)
        )
    return np.where(ok, s, np.nan), np.where(ok, sup_at, 0.0)


def side_window_fit(
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


def smooth_lattice(
    s: FloatArray,
    sigma_nodes: float,
    scales: tuple[float, ...] = (1.0,),
    accept: float = 1.5,
) -> FloatArray:
    """Side-window quadratic smoothing (:func:`side_window_fit`) at ``sigma_nodes``
    times each of ``scales`` (increasing): a node takes the largest scale whose fit is
    still about as good (residual at most ``accept`` times) as the scale below it, so
    flat and gently curved parts get the most smoothing and tighter shapes keep
    their detail. Unknown nodes stay unknown; nodes without a fit keep their value.
    """
    if sigma_nodes < 0.5:
        return s
    valid = np.isfinite(s) & (s > 0)
    q, var = side_window_fit(s, sigma_nodes * scales[0])
    for k in scales[1:]:
        q2, var2 = side_window_fit(s, sigma_nodes * k)
        with np.errstate(invalid="ignore"):
            take = np.isfinite(q2) & (np.abs(q2 - q) <= accept * np.sqrt(var))
        q = np.where(take, q2, q)
        var = np.where(take, var2, var)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(valid & np.isfinite(q) & (q > 0), 1.0 / q, np.where(valid, s, np.nan))


def node_spacing_m(projector: Projector, shape: tuple[int, int], depth_m: float) -> float:
    """Distance between neighbouring lattice nodes on a surface ``depth_m`` away."""
    rows, cols = shape
    step_px = min(
        (projector.width - 1) / max(cols - 1, 1), (projector.height - 1) / max(rows - 1, 1)
    )
    return depth_m * step_px / float(projector.K[0, 0])


def reject_spikes(s: FloatArray, rel: float) -> FloatArray:
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


def fill_holes(s: FloatArray, max_nodes: int) -> tuple[FloatArray, BoolArray]:
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


def node_confidence(
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
    sigma = depth_sigma(np.where(valid, z, 0.0), calibration, settings.disparity_sigma_px)
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


def estimate_surface(
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
    zs, support = smooth_depth(clean_depth(z, settings), settings.smooth_sigma_px)
    p = calibration.projector
    dirs = p.rays(lattice_uv(p, shape))
    k = supersampling(p, shape, zs, settings)
    fine = ((shape[0] - 1) * k + 1, (shape[1] - 1) * k + 1)
    s, sup = intersect_rays(p.rays(lattice_uv(p, fine)), zs, support, calibration, settings)
    s = reject_spikes(s, settings.spike_rel)
    if np.isfinite(s).any():
        spacing = node_spacing_m(p, fine, float(np.nanmedian(s)))
        sigma = min(settings.smooth_m / spacing, settings.smooth_max_nodes)
        s = smooth_lattice(s, sigma, settings.smooth_scales, settings.smooth_accept)
    s, sup = s[::k, ::k], sup[::k, ::k]
    s, filled = fill_holes(s, settings.max_hole_nodes)
    points = dirs * s[..., None]
    conf = node_confidence(points, np.where(filled, 0.5, sup), filled, calibration, settings)
    surface = Surface(points.astype(np.float32), p, {"source": "depth"})
    est = SurfaceEstimate(surface, conf, filled & np.isfinite(s))
    return replace(est, surface=replace(surface, meta={"source": "depth", **est.summary()}))


def supersampling(
    projector: Projector, shape: tuple[int, int], zs: FloatArray, settings: DepthSettings
) -> int:
    """How many times finer than ``shape`` to sample, so that nodes are at most
    ``smooth_m / 2`` apart on the surface (1 for fine lattices, at most 4)."""
    good = zs[np.isfinite(zs)]
    z = float(np.median(good)) if good.size else 1.5
    k = np.ceil(node_spacing_m(projector, shape, z) / (settings.smooth_m / 2))
    return int(np.clip(k, 1, settings.max_supersample))


def dense_shape(projector: Projector, step: int = 4) -> tuple[int, int]:
    """Lattice shape with one node every ``step`` projector pixels."""
    return (projector.height - 1) // step + 1, (projector.width - 1) // step + 1


def is_still(
    gyro: FloatArray, accel: FloatArray, max_rate: float = 0.03, max_accel_std: float = 0.3
) -> bool:
    """Whether IMU samples (N, 3) gyro rad/s and (N, 3) accel m/s^2 show a still device."""
    g = np.asarray(gyro, dtype=np.float64).reshape(-1, 3)
    a = np.asarray(accel, dtype=np.float64).reshape(-1, 3)
    if len(g) < 2:
        return False
    rate = float(np.linalg.norm(np.median(g, axis=0)))
    jitter = float(np.max(np.std(a, axis=0)))
    return rate <= max_rate and jitter <= max_accel_std


class SurfaceFilter:
    """Averages estimates over time while the device is still; restarts when it moves.

    Per node, a running mean of the depth along the ray (so a point stays on its ray),
    weighted by confidence; a node whose new depth jumps more than ``jump_rel`` of its
    depth starts over. At most ``max_frames`` frames are kept in the mean.
    """

    def __init__(self, max_frames: int = 30, jump_rel: float = 0.03) -> None:
        self.max_frames = max_frames
        self.jump_rel = jump_rel
        self._s: FloatArray | None = None
        self._w: FloatArray | None = None
        self._c: FloatArray | None = None
        self._n = 0
        self.current: SurfaceEstimate | None = None

    def reset(self) -> None:
        self._s = self._w = self._c = None
        self._n = 0
        self.current = None

    def update(self, est: SurfaceEstimate, still: bool) -> SurfaceEstimate:
        pts = est.surface.points.astype(np.float64)
        s_new = pts[..., 2]
        c_new = est.confidence.astype(np.float64)
        if not still or self._s is None or self._s.shape != s_new.shape:
            self._s, self._c = s_new.copy(), c_new.copy()
            self._w = np.where(np.isfinite(s_new), np.maximum(c_new, 1e-3), 0.0)
            self._n = 1
            self.current = est
            return est
        assert self._w is not None and self._c is not None
        with np.errstate(invalid="ignore"):
            both = np.isfinite(s_new) & np.isfinite(self._s)
            jump = both & (np.abs(s_new - self._s) > self.jump_rel * self._s)
        w_new = np.where(np.isfinite(s_new), np.maximum(c_new, 1e-3), 0.0)
        cap = np.max(w_new) * self.max_frames if w_new.size else 1.0
        w_old = np.where(jump, 0.0, np.minimum(self._w, cap))
        total = w_old + w_new
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(
                total > 0,
                (np.nan_to_num(self._s) * w_old + np.nan_to_num(s_new) * w_new) / total,
                np.nan,
            )
            c = np.where(total > 0, (self._c * w_old + c_new * w_new) / total, 0.0)
        self._s, self._w, self._c = s, total, c
        self._n = min(self._n + 1, self.max_frames)
        dirs = est.surface.projector.rays(lattice_uv(est.surface.projector, s.shape))
        surface = Surface(
            (dirs * s[..., None]).astype(np.float32), est.surface.projector, dict(est.surface.meta)
        )
        filled = est.filled & ~np.isfinite(self._s) | (est.filled & (w_old == 0))
        self.current = SurfaceEstimate(surface, c.astype(np.float32), filled, self._n)
        return self.current
