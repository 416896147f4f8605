"""Step 3 of the depth pipeline: each projector ray meets the smoothed depth surface.

The point ``s d`` on the ray is moved into frame D, projected into the depth image, and
``s`` updated until the depth it predicts matches the depth measured there (the P-D
baseline is a few centimetres, so this converges in a few steps).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.images import DepthImages
from adaproj_edge.geometry.depth.settings import DepthSettings


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
    images = DepthImages(
        np.where(valid, zs * support, 0.0).astype(np.float32),
        np.where(valid, support, 0.0).astype(np.float32),
        support.astype(np.float32),
        valid.astype(np.float32),
        float(np.median(good)) if good.size else None,
        None,
    )
    return intersect_images(dirs_p, images, calibration, settings)


def intersect_images(
    dirs_p: FloatArray, images: DepthImages, calibration: Calibration, settings: DepthSettings
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
