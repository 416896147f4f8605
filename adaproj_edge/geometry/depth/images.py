"""Steps 1-2 of the depth pipeline on the depth image: range and speckle rejection,
then normalised-convolution smoothing with its support, in float32 scratch."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.depth.cuts import jump_pixels
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.depth.workspace import Workspace

_KERNEL = np.ones((3, 3), np.uint8)


@dataclass(frozen=True)
class DepthImages:
    """The smoothed depth as ray intersection samples it, float32 (h, w) (scratch
    arrays of a :class:`Workspace`: valid until its next frame).

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
    values: NDArray[np.float32], inner: BoolArray, outer: BoolArray, work: Workspace
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
        below = np.less(flat, lo, out=work.get("below", flat.shape, np.bool_))
        within = np.greater_equal(flat, lo, out=work.get("within", flat.shape, np.bool_))
        within &= np.less_equal(flat, hi, out=work.get("tmp", flat.shape, np.bool_))
    out: list[float | None] = []
    for mask, n in zip(masks, counts, strict=True):
        if n == 0:
            out.append(None)
            continue
        kth = [n // 2] if n % 2 else [n // 2 - 1, n // 2]
        mid = None
        if below is not None and within is not None:
            sel = work.get("sel", flat.shape, np.bool_)
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


def clean_images(
    z: FloatArray,
    settings: DepthSettings,
    positive: bool,
    work: Workspace,
    sensor: SensorModel | None = None,
) -> tuple[BoolArray, NDArray[np.float32], BoolArray | None]:
    """Step 1 in scratch: mask of the pixels :func:`clean_depth` keeps (and, if
    ``positive``, z > 0), the float32 depth where in range, 0 elsewhere, and (given a
    ``sensor``) the jump pixels (:func:`~adaproj_edge.geometry.depth.cuts.jump_pixels`;
    else None).

    Given the ``sensor``'s noise model, the pixels on either side of a depth jump are
    dropped too (flying pixels, and the pixels the smoothing would mix across it): those
    whose 3x3 neighbourhood spans more than ``flying_sigmas`` of its depth error plus
    ``speckle_rel`` of its depth (a floor seen grazing spans less)."""
    shape = z.shape
    ok = work.get("ok", shape, np.bool_)
    tmp = work.get("tmp", shape, np.bool_)
    with np.errstate(invalid="ignore"):
        np.greater_equal(z, settings.min_depth_m, out=ok)
        ok &= np.less_equal(z, settings.max_depth_m, out=tmp)
        if positive and not settings.min_depth_m > 0:
            ok &= np.greater(z, 0.0, out=tmp)
        z32 = work.get("z32", shape, np.float32)
        z32.fill(0.0)
        np.copyto(z32, z, casting="same_kind", where=ok)
        med = work.get("med", shape, np.float32)
        cv2.medianBlur(z32, 5, dst=med)
        # speckle, in float64 as before: drop |z - median| > speckle_rel z
        dev = work.get("dev", shape, np.float64)
        lim = work.get("lim", shape, np.float64)
        np.copyto(lim, med)  # (one type in the subtraction is faster)
        np.subtract(z, lim, out=dev)
        np.abs(dev, out=dev)
        np.multiply(z, settings.speckle_rel, out=lim)
        ok &= np.less_equal(dev, lim, out=tmp)
        jumps = None
        if sensor is not None:
            jumps = _drop_jumps(ok, z32, settings, sensor, work)
    return ok, z32, jumps


def _drop_jumps(
    ok: BoolArray,
    z32: NDArray[np.float32],
    settings: DepthSettings,
    sensor: SensorModel,
    work: Workspace,
) -> BoolArray:
    """Clear ``ok`` where the 3x3 neighbourhood of kept depths spans a jump; returns
    the jump pixels of :func:`~adaproj_edge.geometry.depth.cuts.jump_pixels` (judged
    on the same neighbourhoods)."""
    shape = ok.shape
    zk = np.multiply(z32, ok, out=work.get("zk", shape, np.float32))
    hi = cv2.dilate(zk, _KERNEL, dst=work.get("hi", shape, np.float32))
    zk[~ok] = np.float32(1e9)
    lo = cv2.erode(zk, _KERNEL, dst=work.get("lo", shape, np.float32))
    # limit = (flying_sigmas sigma(hi) / hi + speckle_rel) hi, sigma(z) = c z^2
    c = np.float32(settings.flying_sigmas * sensor.disparity_total_px / sensor.fb)
    lim = np.multiply(hi, c, out=work.get("flim", shape, np.float32))
    lim += np.float32(settings.speckle_rel)
    lim *= hi
    np.subtract(hi, lo, out=zk)
    jumps = jump_pixels(hi, zk, sensor, settings.flying_sigmas, settings.jump_ray_deg, work)
    ok &= np.less_equal(zk, lim, out=work.get("tmp", shape, np.bool_))
    return jumps


def smooth_images(
    ok: BoolArray, z32: NDArray[np.float32], sigma_px: float, work: Workspace
) -> tuple[NDArray[np.float32], NDArray[np.float32], BoolArray]:
    """Step 2: :func:`smooth_depth` of ``z32`` where ``ok``, in float32 scratch: smoothed depth
    (0 where there is none), support, and where there is a smoothed depth."""
    shape = ok.shape
    m = work.get("m", shape, np.float32)
    np.copyto(m, ok)
    # scratch of earlier steps is reused once they are done: "med" of _clean, its z32
    zz = np.multiply(z32, m, out=work.get("med", shape, np.float32))
    num = work.get("num", shape, np.float32)
    den = work.get("den", shape, np.float32)
    cv2.GaussianBlur(zz, (0, 0), sigma_px, dst=num, borderType=cv2.BORDER_CONSTANT)
    cv2.GaussianBlur(m, (0, 0), sigma_px, dst=den, borderType=cv2.BORDER_CONSTANT)
    zs = work.get("z32", shape, np.float32)  # z32 is used up (zz)
    zs.fill(0.0)
    has = np.greater(den, np.float32(1e-3), out=work.get("has", shape, np.bool_))
    np.divide(num, den, out=zs, where=has)
    return zs, den, has


def sampled_images(
    zs: NDArray[np.float32],
    support: NDArray[np.float32],
    has: BoolArray,
    settings: DepthSettings,
    work: Workspace,
) -> DepthImages:
    """The images ray intersection samples, from :func:`smooth_images`."""
    shape = zs.shape
    # support >= min_support in float64 (so > 1e-3: there is a smoothed depth): the
    # float32 support against the least float32 that is not below min_support
    least = np.float32(settings.min_support)
    if float(least) < settings.min_support:
        least = np.nextafter(least, np.float32(np.inf))
    usable = np.greater_equal(support, least, out=work.get("usable", shape, np.bool_))
    if not settings.min_support > 1e-3:
        usable &= has
    wgt = np.multiply(support, usable, out=work.get("wgt", shape, np.float32))
    # float32(zs * support) as before in float64: a product of two float32 is exact there
    num = np.multiply(zs, wgt, out=work.get("inum", shape, np.float32))
    mask = work.get("m", shape, np.float32)  # the support's weights are used up
    np.copyto(mask, usable)
    return DepthImages(num, wgt, support, mask, *_medians(zs, usable, has, work))


def clean_depth(depth_m: FloatArray, settings: DepthSettings) -> FloatArray:
    """Range check and speckle rejection; (h, w) metres with NaN where invalid."""
    z = np.asarray(depth_m, dtype=np.float64)
    return np.where(clean_images(z, settings, False, Workspace())[0], z, np.nan)


def smooth_depth(z: FloatArray, sigma_px: float) -> tuple[FloatArray, FloatArray]:
    """Normalised-convolution smoothing: (smoothed z, support), both (h, w)."""
    ok = np.isfinite(z)
    z32 = np.where(ok, z, 0.0).astype(np.float32)
    zs, den, has = smooth_images(ok, z32, sigma_px, Workspace())
    return np.where(has, zs, np.nan).astype(np.float64), den.astype(np.float64)
