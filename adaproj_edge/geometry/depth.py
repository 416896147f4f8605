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
   from it (the fits are evaluated at its nodes only; the finer lattice is their
   data); small holes (not touching the frame border) are filled from their
   neighbours;
5. every node gets a confidence in [0, 1] from support, the stereo noise expected at
   its depth (grows with z^2), the viewing angle, and whether it was filled.

:class:`SurfaceFilter` averages estimates over time while the device is still
(:func:`~adaproj_edge.motion.tracker.is_still` decides that from IMU samples).
Grazing angles, holes and surfaces out of range lower coverage and confidence; they never raise.
Pure: arrays in, arrays out.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface


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


_RAYS: dict[tuple[bytes, int, int, tuple[int, int]], FloatArray] = {}


def _lattice_rays(projector: Projector, shape: tuple[int, int]) -> FloatArray:
    """``projector.rays(lattice_uv(projector, shape))``, kept for the next frames
    (read-only)."""
    key = (projector.K.tobytes(), projector.width, projector.height, shape)
    rays = _RAYS.get(key)
    if rays is None:
        if len(_RAYS) > 16:
            _RAYS.clear()
        rays = projector.rays(lattice_uv(projector, shape))
        rays.setflags(write=False)
        _RAYS[key] = rays
    return rays


def depth_sigma(z: FloatArray, calibration: Calibration, disparity_sigma_px: float) -> FloatArray:
    """Stereo depth noise (m) at depth ``z``: z^2 / (f B) * sigma_disparity."""
    d = calibration.depth
    return z * z / (d.focal * d.baseline_m) * disparity_sigma_px


class _Workspace(threading.local):
    """Per-thread scratch arrays, reused from frame to frame: frame-sized temporaries
    allocated afresh are returned to the OS after each frame and cost page faults
    (about as much as the arithmetic on them) when allocated again."""

    def __init__(self) -> None:
        self.arrays: dict[tuple[str, tuple[int, ...], str], NDArray[Any]] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype: type[Any] = np.float64) -> NDArray[Any]:
        key = (name, shape, np.dtype(dtype).str)
        if key not in self.arrays:
            if len(self.arrays) > 64:  # sizes changed (another frame or lattice size)
                self.arrays.clear()
            self.arrays[key] = np.empty(shape, dtype)
        return self.arrays[key]


_WORK = _Workspace()


@dataclass(frozen=True)
class _DepthImages:
    """The smoothed depth as ray intersection samples it, float32 (h, w) (scratch
    arrays of :data:`_WORK`: valid until the next frame on this thread).

    ``num`` is smoothed depth x support and ``wgt`` the support where the depth is
    usable (finite, support >= ``min_support``), 0 elsewhere; ``sup`` the support
    everywhere; ``mask`` 1 where usable. ``z_usable`` / ``z_any``: median smoothed
    depth over the usable pixels / over all with a smoothed depth (None if none).
    """

    num: NDArray[np.float32]
    wgt: NDArray[np.float32]
    sup: NDArray[np.float32]
    mask: NDArray[np.float32]
    z_usable: float | None
    z_any: float | None


def _medians(
    values: NDArray[np.float32], inner: BoolArray, outer: BoolArray
) -> tuple[float | None, float | None]:
    """``np.median(values[mask].astype(np.float64))`` for ``inner`` and for ``outer``
    (None where empty), exactly and mostly without sorting: the middle values are
    looked for between two quantiles of a strided sample, and the whole set partitioned
    only if they are not there."""
    flat = values.reshape(-1)
    masks = inner.reshape(-1), outer.reshape(-1)
    counts = [int(np.count_nonzero(m)) for m in masks]
    stride = max(1, flat.size // 4096)
    sample = np.sort(flat[::stride][masks[0][::stride]])
    below = within = None
    if counts[0] > 8192 and sample.size >= 256:
        lo, hi = sample[sample.size * 7 // 16], sample[sample.size * 9 // 16]
        below = np.less(flat, lo, out=_WORK.get("below", flat.shape, np.bool_))
        within = np.greater_equal(flat, lo, out=_WORK.get("within", flat.shape, np.bool_))
        within &= np.less_equal(flat, hi, out=_WORK.get("tmp", flat.shape, np.bool_))
    out: list[float | None] = []
    for mask, n in zip(masks, counts, strict=True):
        if n == 0:
            out.append(None)
            continue
        kth = [n // 2] if n % 2 else [n // 2 - 1, n // 2]
        mid = None
        if below is not None and within is not None:
            sel = _WORK.get("sel", flat.shape, np.bool_)
            k0 = int(np.count_nonzero(np.logical_and(below, mask, out=sel)))
            inside = flat[np.logical_and(within, mask, out=sel)]
            if k0 <= kth[0] and kth[-1] < k0 + inside.size:
                mid, kth = inside, [k - k0 for k in kth]
        if mid is None:
            mid = flat[mask]
        mid.partition(kth)
        if len(kth) == 1:
            out.append(float(mid[kth[0]]))
        else:
            out.append((float(mid[kth[0]]) + float(mid[kth[1]])) / 2)
    return out[0], out[1]


def _clean(
    z: FloatArray, settings: DepthSettings, positive: bool
) -> tuple[BoolArray, NDArray[np.float32]]:
    """Mask of the pixels :func:`clean_depth` keeps (and, if ``positive``, z > 0), and
    the float32 depth where in range, 0 elsewhere (scratch)."""
    shape = z.shape
    ok = _WORK.get("ok", shape, np.bool_)
    tmp = _WORK.get("tmp", shape, np.bool_)
    with np.errstate(invalid="ignore"):
        np.greater_equal(z, settings.min_depth_m, out=ok)
        ok &= np.less_equal(z, settings.max_depth_m, out=tmp)
        if positive and not settings.min_depth_m > 0:
            ok &= np.greater(z, 0.0, out=tmp)
        z32 = _WORK.get("z32", shape, np.float32)
        z32.fill(0.0)
        np.copyto(z32, z, casting="same_kind", where=ok)
        med = _WORK.get("med", shape, np.float32)
        cv2.medianBlur(z32, 5, dst=med)
        # speckle, in float64 as before: drop |z - median| > speckle_rel z
        dev = _WORK.get("dev", shape, np.float64)
        lim = _WORK.get("lim", shape, np.float64)
        np.copyto(lim, med)  # (one type in the subtraction is faster)
        np.subtract(z, lim, out=dev)
        np.abs(dev, out=dev)
        np.multiply(z, settings.speckle_rel, out=lim)
        ok &= np.less_equal(dev, lim, out=tmp)
    return ok, z32


def _smooth(
    ok: BoolArray, z32: NDArray[np.float32], sigma_px: float
) -> tuple[NDArray[np.float32], NDArray[np.float32], BoolArray]:
    """:func:`smooth_depth` of ``z32`` where ``ok``, in float32 scratch: smoothed depth
    (0 where there is none), support, and where there is a smoothed depth."""
    shape = ok.shape
    m = _WORK.get("m", shape, np.float32)
    np.copyto(m, ok)
    # scratch of earlier steps is reused once they are done: "med" of _clean, its z32
    zz = np.multiply(z32, m, out=_WORK.get("med", shape, np.float32))
    num = _WORK.get("num", shape, np.float32)
    den = _WORK.get("den", shape, np.float32)
    cv2.GaussianBlur(zz, (0, 0), sigma_px, dst=num, borderType=cv2.BORDER_CONSTANT)
    cv2.GaussianBlur(m, (0, 0), sigma_px, dst=den, borderType=cv2.BORDER_CONSTANT)
    zs = _WORK.get("z32", shape, np.float32)  # z32 is used up (zz)
    zs.fill(0.0)
    has = np.greater(den, np.float32(1e-3), out=_WORK.get("has", shape, np.bool_))
    np.divide(num, den, out=zs, where=has)
    return zs, den, has


def _images(
    zs: NDArray[np.float32], support: NDArray[np.float32], has: BoolArray, settings: DepthSettings
) -> _DepthImages:
    """The images :func:`intersect_rays` samples, from :func:`_smooth`."""
    shape = zs.shape
    # support >= min_support in float64 (so > 1e-3: there is a smoothed depth): the
    # float32 support against the least float32 that is not below min_support
    least = np.float32(settings.min_support)
    if float(least) < settings.min_support:
        least = np.nextafter(least, np.float32(np.inf))
    usable = np.greater_equal(support, least, out=_WORK.get("usable", shape, np.bool_))
    if not settings.min_support > 1e-3:
        usable &= has
    wgt = np.multiply(support, usable, out=_WORK.get("wgt", shape, np.float32))
    # float32(zs * support) as before in float64: a product of two float32 is exact there
    num = np.multiply(zs, wgt, out=_WORK.get("inum", shape, np.float32))
    mask = _WORK.get("m", shape, np.float32)  # the support's weights are used up
    np.copyto(mask, usable)
    return _DepthImages(num, wgt, support, mask, *_medians(zs, usable, has))


def clean_depth(depth_m: FloatArray, settings: DepthSettings) -> FloatArray:
    """Range check and speckle rejection; (h, w) metres with NaN where invalid."""
    z = np.asarray(depth_m, dtype=np.float64)
    return np.where(_clean(z, settings, positive=False)[0], z, np.nan)


def smooth_depth(z: FloatArray, sigma_px: float) -> tuple[FloatArray, FloatArray]:
    """Normalised-convolution smoothing: (smoothed z, support), both (h, w)."""
    ok = np.isfinite(z)
    z32 = np.where(ok, z, 0.0).astype(np.float32)
    zs, den, has = _smooth(ok, z32, sigma_px)
    return np.where(has, zs, np.nan).astype(np.float64), den.astype(np.float64)


def _maps(uv: FloatArray) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """``cv2.remap`` maps for pixel coordinates ``uv`` (..., 2); non-finite ones -> -10."""
    uv = np.where(np.isfinite(uv), uv, -10.0)
    return uv[..., 0].astype(np.float32), uv[..., 1].astype(np.float32)


def _sample(img: NDArray[np.float32], maps: tuple[NDArray[np.float32], ...]) -> FloatArray:
    """Bilinear sample of ``img`` (h, w) at :func:`_maps`; 0 outside."""
    mx, my = maps
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
    valid = np.isfinite(zs) & (support >= settings.min_support)
    good = zs[valid]
    images = _DepthImages(
        np.where(valid, zs * support, 0.0).astype(np.float32),
        np.where(valid, support, 0.0).astype(np.float32),
        support.astype(np.float32),
        valid.astype(np.float32),
        float(np.median(good)) if good.size else None,
        None,
    )
    return _intersect(dirs_p, images, calibration, settings)


def _intersect(
    dirs_p: FloatArray, images: _DepthImages, calibration: Calibration, settings: DepthSettings
) -> tuple[FloatArray, FloatArray]:
    """:func:`intersect_rays` on the sampled images."""
    T = calibration.T_P_D
    R, t = T[:3, :3], T[:3, 3]
    a = dirs_p @ R  # R^T d: ray direction in D
    b = -R.T @ t  # projector centre in D
    K = calibration.depth.K
    num, wgt = images.num, images.wgt
    s = np.full(dirs_p.shape[:-1], images.z_usable if images.z_usable is not None else 1.0)
    z_meas = np.full_like(s, np.nan)
    KT, az = K.T, a[..., 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        for _ in range(settings.iterations):
            x = s[..., None] * a + b
            maps = _maps((x @ KT)[..., :2] / x[..., 2:3])
            w = _sample(wgt, maps)
            z_meas = np.where(w > 1e-3, _sample(num, maps) / w, np.nan)
            s_new = (z_meas - b[2]) / az
            s = np.where(np.isfinite(s_new) & (s_new > 0), s_new, s)
        x = s[..., None] * a + b
        maps = _maps((x @ KT)[..., :2] / x[..., 2:3])
    sup_at = _sample(images.sup, maps)
    mask_at = _sample(images.mask, maps)
    with np.errstate(invalid="ignore"):
        residual = np.abs(x[..., 2] - z_meas)
        ok = (
            np.isfinite(z_meas)
            & (mask_at > 0.5)
            & (residual < 0.002 + 0.01 * s)
            & (s > settings.min_depth_m)
        )
    return np.where(ok, s, np.nan), np.where(ok, sup_at, 0.0)


_POWERS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))  # the quadratic basis x^a y^b
# the five windows (whole, left, right, up, down) as the half of the x and of the y axis
# each keeps: 0 = all offsets, 1 = offsets <= 0, 2 = offsets >= 0
_HALVES = ((0, 0), (1, 0), (2, 0), (0, 1), (0, 2))
_MOMENTS = tuple((a, b) for a in range(5) for b in range(5 - a))  # x^a y^b, a + b <= 4
_MOMENT_A, _MOMENT_B = np.array(_MOMENTS).T
_POWER_A, _POWER_B = np.array(_POWERS).T
# the x half of the whole, left, right windows; the y half of the up, down ones
_HX, _HY = np.arange(3), np.arange(2)
# entry (i, j) of the normal matrix: the moment of the product of basis functions i, j
_NORMAL = np.array([[_MOMENTS.index((a + c, b + d)) for c, d in _POWERS] for a, b in _POWERS])


def _axis_kernels(r: int, sigma: float) -> FloatArray:
    """(3 halves, 5 powers, 2r + 1): Gaussian x indicator of the half x (d / r)^p."""
    d = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-(d * d) / (2 * sigma**2))
    t = d / r
    half = np.stack([np.ones_like(d), d <= 0, d >= 0])
    return np.stack([g * half * t**p for p in range(5)], axis=1)


def _window_sums(a: FloatArray, kernels: FloatArray, step: int) -> FloatArray:
    """Correlation along axis 0 at every ``step``-th position, zeros outside.

    ``out[k, i, f] = sum_d kernels[k, d + r] * a[i * step + d, f]`` for ``a`` (n, f) and
    ``kernels`` (nk, 2r + 1); returns (nk, ceil(n / step), f). As a banded matrix product
    when the window is not much narrower than the axis, else over strided windows.
    """
    n, f = a.shape
    nk, width = kernels.shape
    r = width // 2
    m = (n - 1) // step + 1
    if n <= 4 * width:
        band = np.zeros((nk, m, n + 2 * r))
        s0, s1, s2 = band.strides  # row i of the band holds the kernel from column i * step
        diag = np.lib.stride_tricks.as_strided(band, (nk, m, width), (s0, s1 + step * s2, s2))
        diag[...] = kernels[:, None, :]
        return (band[:, :, r : r + n].reshape(nk * m, n) @ a).reshape(nk, m, f)
    padded = np.zeros((n + 2 * r, f))
    padded[r : r + n] = a
    win = np.lib.stride_tricks.sliding_window_view(padded, width, axis=0)[::step]
    out = np.ascontiguousarray(win).reshape(m * f, width) @ kernels.T
    return np.ascontiguousarray(out.reshape(m, f, nk).transpose(2, 0, 1))


def _window_moments(
    imgs: FloatArray, sigma: float, step: int, mom: FloatArray, bq: FloatArray, sqq: FloatArray
) -> FloatArray:
    """The weighted sums over the five windows of every kept node, for one scale.

    ``imgs`` (rows, cols, 3) holds m, m q and m q^2; written are ``mom`` (15, 5, ny, nx),
    the sums of m x^a y^b (:data:`_MOMENTS`), ``bq`` (6, 5, ny, nx), of m q x^a y^b
    (:data:`_POWERS`), and ``sqq`` (5, ny, nx), of m q^2; returns sum(w^2) / sum(w) of
    the weights of each window (5,). The weights are separable, so each sum is
    ``Ky @ img @ Kx.T`` with banded ``Kx``, ``Ky`` (:func:`_window_sums`).
    """
    rows, cols, _ = imgs.shape
    ny, nx = (rows - 1) // step + 1, (cols - 1) // step + 1
    r = int(np.ceil(2 * sigma))
    k1 = _axis_kernels(r, sigma)  # (half, power, offset)
    # along x, every (half, power) on the three images
    sx = _window_sums(imgs.transpose(1, 0, 2).reshape(cols, rows * 3), k1.reshape(15, -1), step)
    sx = sx.reshape(3, 5, nx, rows, 3).transpose(3, 4, 0, 1, 2)  # (rows, img, hx, a, nx)
    xm = sx[:, 0]  # m x^a
    xq = np.concatenate([sx[:, 1, :, :3], sx[:, 2, :, :1]], axis=2)  # m q x^0..2, m q^2
    # along y: the whole column with every x half; its upper, lower half with the whole x
    fm = _window_sums(xm.reshape(rows, -1), k1[0], step).reshape(5, ny, 3, 5, nx)
    fq = _window_sums(xq.reshape(rows, -1), k1[0, :3], step).reshape(3, ny, 3, 4, nx)
    um = _window_sums(xm[:, 0].reshape(rows, -1), k1[1:].reshape(10, -1), step)
    uq = _window_sums(xq[:, 0].reshape(rows, -1), k1[1:, :3].reshape(6, -1), step)
    um = um.reshape(2, 5, ny, 5, nx)
    uq = uq.reshape(2, 3, ny, 4, nx)
    hx, hy = _HX[None], _HY[None]
    a, b = _MOMENT_A[:, None], _MOMENT_B[:, None]
    mom[:, :3] = fm[b, :, hx, a]
    mom[:, 3:] = um[hy, b, :, a]
    a, b = _POWER_A[:, None], _POWER_B[:, None]
    bq[:, :3] = fq[b, :, hx, a]
    bq[:, 3:] = uq[hy, b, :, a]
    sqq[:3] = fq[0, :, _HX, 3]
    sqq[3:] = uq[_HY, 0, :, 3]
    # sum(w^2) / sum(w) of each window's weights w
    s1, s2 = np.sum(k1[:, 0], axis=1), np.sum(k1[:, 0] ** 2, axis=1)
    return np.array([s2[hx] * s2[hy] / (s1[hx] * s1[hy]) for hx, hy in _HALVES])


def _solve_spd(A: FloatArray, B: FloatArray) -> FloatArray:
    """Solve many small symmetric positive definite systems at once, overwriting the
    arguments: ``A`` (n, n, N) and ``B`` (n, c, N) hold N systems along the last axis;
    returns X (n, c, N) with ``A X = B``. Gaussian elimination without pivoting (stable
    for these matrices), each step one array operation over all systems.
    """
    n = A.shape[0]
    for k in range(n - 1):
        f = A[k + 1 :, k] / A[k, k]
        A[k + 1 :, k + 1 :] -= f[:, None] * A[k, None, k + 1 :]
        B[k + 1 :] -= f[:, None] * B[k, None]
    X = np.empty(B.shape)
    for k in range(n - 1, -1, -1):
        acc = B[k] - np.sum(A[k, k + 1 :, None] * X[k + 1 :], axis=0)
        X[k] = acc / A[k, k]
    return X


def _side_window_fits(
    s: FloatArray,
    sigmas: tuple[float, ...],
    min_weight: float = 3.0,
    switch: float = 3.0,
    step: int = 1,
) -> tuple[FloatArray, FloatArray]:
    """:func:`side_window_fit` at several ``sigmas`` at once: (q, rss), each
    (len(sigmas), ceil(rows / step), ceil(cols / step))."""
    valid = np.isfinite(s) & (s > 0)
    q = np.where(valid, 1.0 / np.where(valid, s, 1.0), 0.0)
    m = valid.astype(np.float64)
    imgs = np.stack([m, m * q, m * q * q], axis=-1)
    valid = valid[::step, ::step]
    ns, (ny, nx) = len(sigmas), valid.shape
    shape = (ns, 5, ny, nx)  # scale, window, node
    mom = _WORK.get("mom", (15, *shape))
    bq = _WORK.get("bq", (6, *shape))
    sqq = _WORK.get("sqq", shape)
    wbar = np.empty((ns, 5, 1, 1))  # sum(w^2) / sum(w) of the weights of each window
    for i, sigma in enumerate(sigmas):
        wbar[i, :, 0, 0] = _window_moments(imgs, sigma, step, mom[:, i], bq[:, i], sqq[i])
    w00 = mom[0]
    ok = valid & (w00 >= min_weight)
    bq[:, ~ok] = 0.0
    # the normal equations (A + 1e-9 I) c = b of every scale, window and node (A = I
    # where there is no fit), eliminated last variable first: the last pivot is then
    # 1 / (A^-1)_00
    n = ok.size
    A = np.take(mom.reshape(15, n), _NORMAL, axis=0, out=_WORK.get("A", (6, 6, n)), mode="clip")
    A[:, :, ~ok.reshape(-1)] = np.eye(6)[:, :, None]
    A[np.arange(6), np.arange(6)] += 1e-9
    B = _WORK.get("B", (6, 1, n))
    B[:, 0] = bq.reshape(6, n)[::-1]
    coef = _solve_spd(A[::-1, ::-1], B)[::-1, 0].reshape(6, *shape)
    a00 = (1.0 / A[0, 0]).reshape(shape)
    # weighted residual sum of squares from the moments: S - 2 c.b + c^T A c (A without
    # the 1e-9; where there is no fit c = 0)
    cAc = np.zeros(shape)
    for i in range(6):
        Ac = np.sum(mom[_NORMAL[i]] * coef, axis=0)
        Ac *= coef[i]
        cAc += Ac
    res = sqq - 2 * np.sum(coef * bq, axis=0) + cAc
    with np.errstate(invalid="ignore", divide="ignore"):
        R = np.where(ok, np.maximum(res, 0.0) / w00, np.inf)  # (scale, window, ny, nx)
    var = R * a00 * wbar
    side = 1 + np.argmin(R[:, 1:], axis=1)
    best_side = np.take_along_axis(R[:, 1:], (side - 1)[:, None], axis=1)[:, 0]
    choice = np.where(R[:, 0] > switch * best_side, side, 0)
    choice = np.where(ok[:, 0], choice, np.where(ok.any(axis=1), np.argmax(ok, axis=1), -1))
    pick = np.maximum(choice, 0)[:, None]
    qf = np.take_along_axis(coef[0], pick, axis=1)[:, 0]
    vf = np.take_along_axis(var, pick, axis=1)[:, 0]
    good = valid & (choice >= 0) & (qf > 0)
    return np.where(good, qf, np.nan), np.where(good, vf, np.inf)


def side_window_fit(
    s: FloatArray,
    sigma_nodes: float,
    min_weight: float = 3.0,
    switch: float = 3.0,
    step: int = 1,
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

    Only the nodes ``[::step, ::step]`` are fitted (the whole lattice is data).

    Returns
    -------
    q : (ceil(rows / step), ceil(cols / step)) fitted inverse depth, NaN where no fit
    rss : same shape, weighted mean squared residual of the chosen window
    """
    q, rss = _side_window_fits(s, (sigma_nodes,), min_weight, switch, step)
    return q[0], rss[0]


def smooth_lattice(
    s: FloatArray,
    sigma_nodes: float,
    scales: tuple[float, ...] = (1.0,),
    accept: float = 1.5,
    step: int = 1,
) -> FloatArray:
    """Side-window quadratic smoothing (:func:`side_window_fit`) at ``sigma_nodes``
    times each of ``scales`` (increasing): a node takes the largest scale whose fit is
    still about as good (residual at most ``accept`` times) as the scale below it, so
    flat and gently curved parts get the most smoothing and tighter shapes keep
    their detail. Unknown nodes stay unknown; nodes without a fit keep their value.

    Returns the nodes ``[::step, ::step]`` (each depends only on the fits there; the
    whole lattice is data).
    """
    if sigma_nodes < 0.5:
        return s if step == 1 else s[::step, ::step]
    valid = (np.isfinite(s) & (s > 0))[::step, ::step]
    qs, vs = _side_window_fits(s, tuple(sigma_nodes * k for k in scales), step=step)
    q, var = qs[0], vs[0]
    for q2, var2 in zip(qs[1:], vs[1:], strict=True):
        with np.errstate(invalid="ignore"):
            take = np.isfinite(q2) & (np.abs(q2 - q) <= accept * np.sqrt(var))
        q = np.where(take, q2, q)
        var = np.where(take, var2, var)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(
            valid & np.isfinite(q) & (q > 0), 1.0 / q, np.where(valid, s[::step, ::step], np.nan)
        )


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
    p = calibration.projector
    s, sup, filled = _lattice_depths(depth_m, calibration, shape, settings)
    points = _lattice_rays(p, shape) * s[..., None]
    conf = node_confidence(points, np.where(filled, 0.5, sup), filled, calibration, settings)
    surface = Surface(points.astype(np.float32), p, {"source": "depth"})
    est = SurfaceEstimate(surface, conf, filled & np.isfinite(s))
    return replace(est, surface=replace(surface, meta={"source": "depth", **est.summary()}))


def _lattice_depths(
    depth_m: FloatArray,
    calibration: Calibration,
    shape: tuple[int, int],
    settings: DepthSettings,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Steps 1-4 of :func:`estimate_surface`: the depth along each lattice ray
    (rows, cols) (NaN where unknown), the support there and the filled nodes."""
    z = np.asarray(depth_m, dtype=np.float64)
    if z.shape != (calibration.depth.height, calibration.depth.width):
        z = cv2.resize(
            np.nan_to_num(z, nan=0.0).astype(np.float32),
            (calibration.depth.width, calibration.depth.height),
            interpolation=cv2.INTER_NEAREST,
        ).astype(np.float64)
    ok, z32 = _clean(z, settings, positive=True)
    images = _images(*_smooth(ok, z32, settings.smooth_sigma_px), settings)
    p = calibration.projector
    k = _supersampling(p, shape, images.z_any, settings)
    fine = ((shape[0] - 1) * k + 1, (shape[1] - 1) * k + 1)
    s, sup = _intersect(_lattice_rays(p, fine), images, calibration, settings)
    s = reject_spikes(s, settings.spike_rel)
    if np.isfinite(s).any():
        spacing = node_spacing_m(p, fine, float(np.nanmedian(s)))
        sigma = min(settings.smooth_m / spacing, settings.smooth_max_nodes)
        s = smooth_lattice(s, sigma, settings.smooth_scales, settings.smooth_accept, step=k)
    else:
        s = s[::k, ::k]
    s, filled = fill_holes(s, settings.max_hole_nodes)
    return s, sup[::k, ::k], filled


def supersampling(
    projector: Projector, shape: tuple[int, int], zs: FloatArray, settings: DepthSettings
) -> int:
    """How many times finer than ``shape`` to sample, so that nodes are at most
    ``smooth_m / 2`` apart on the surface (1 for fine lattices, at most 4)."""
    good = zs[np.isfinite(zs)]
    return _supersampling(projector, shape, float(np.median(good)) if good.size else None, settings)


def _supersampling(
    projector: Projector, shape: tuple[int, int], z_median: float | None, settings: DepthSettings
) -> int:
    z = 1.5 if z_median is None else z_median
    k = np.ceil(node_spacing_m(projector, shape, z) / (settings.smooth_m / 2))
    return int(np.clip(k, 1, settings.max_supersample))


def dense_shape(projector: Projector, step: int = 4) -> tuple[int, int]:
    """Lattice shape with one node every ``step`` projector pixels."""
    return (projector.height - 1) // step + 1, (projector.width - 1) // step + 1


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
