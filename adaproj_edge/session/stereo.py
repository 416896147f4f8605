"""An OAK-D-like stereo error model: true depth in, a depth frame as the camera gives it.

- depth from disparity ``d = f B / z``: white plus spatially correlated disparity
  noise (block matching), so the depth error grows with z^2;
- disparity quantised to 1/2^bits pixel (subpixel mode), then median-filtered as the
  device does (``median`` = 0, 3 or 5; the board's 7x7 is approximated by 5x5);
- invalid (0) pixels: beyond the disparity search range (too close) or too far, at
  depth discontinuities (left-right check), in the left border band the other camera
  does not see, at grazing angles (more likely the more grazing), random dropouts.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.calibration import DepthCameraModel


@dataclass(frozen=True)
class StereoNoise:
    """Parameters of the stereo error model (pixels of disparity unless stated)."""

    white_px: float = 0.1
    correlated_px: float = 0.1
    correlation_px: float = 4.0
    subpixel_bits: int = 3
    max_disparity_px: float = 95.0
    max_depth_m: float = 12.0
    dropout: float = 0.01
    grazing_cos: float = 0.3
    edge_jump: float = 0.04
    median: int = 5


def normals_cos(points: FloatArray) -> FloatArray:
    """|cos| of the angle between the surface normal and the view ray, (h, w); NaN = none."""
    dx = np.gradient(points, axis=1)
    dy = np.gradient(points, axis=0)
    n = np.cross(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        ray = points / np.linalg.norm(points, axis=-1, keepdims=True)
        return np.abs(np.sum(n * ray, axis=-1))  # type: ignore[no-any-return]


def stereo_depth(
    points: FloatArray, model: DepthCameraModel, noise: StereoNoise, rng: np.random.Generator
) -> NDArray[np.uint16]:
    """Depth frame (h, w) uint16 mm of true points (h, w, 3) in frame D (NaN = none)."""
    z = points[..., 2]
    h, w = z.shape
    valid = np.isfinite(z) & (z > 0)
    zt = np.where(valid, z, 1.0)
    fb = model.focal * model.baseline_m
    d = fb / zt
    field = rng.normal(size=(h, w)).astype(np.float32)
    sigma = noise.correlation_px
    field = cv2.GaussianBlur(field, (0, 0), sigma).astype(np.float64)
    field *= noise.correlated_px / max(float(field.std()), 1e-12)
    dn = d + field + rng.normal(scale=noise.white_px, size=(h, w))
    q = 2.0**noise.subpixel_bits
    counts = np.clip(np.round(np.where(valid, dn, 0.0) * q), 0, 65535).astype(np.uint16)
    if noise.median:
        counts = np.asarray(cv2.medianBlur(counts, noise.median), np.uint16)  # as on the device
    dq = counts.astype(np.float64) / q
    valid &= (
        (dq > 0) & (dq <= noise.max_disparity_px) & (fb / np.maximum(dq, 1e-9) < noise.max_depth_m)
    )
    # left-right check fails at depth discontinuities and where only one camera sees
    zz = np.where(valid, zt, np.nan)
    with np.errstate(invalid="ignore"):
        jump = np.zeros((h, w), bool)
        jx = np.abs(np.diff(zz, axis=1)) > noise.edge_jump * zz[:, 1:]
        jy = np.abs(np.diff(zz, axis=0)) > noise.edge_jump * zz[1:, :]
        jump[:, 1:] |= jx
        jump[:, :-1] |= jx
        jump[1:, :] |= jy
        jump[:-1, :] |= jy
        edge = ~np.isfinite(zz)
        edge = cv2.dilate(edge.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    jump = cv2.dilate(jump.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    valid &= ~jump
    valid &= ~(edge & (rng.random((h, w)) < 0.5))
    cols = np.arange(w)[None, :]
    valid &= cols >= d  # the left border band the right camera does not see
    cos = normals_cos(np.where(valid[..., None], points, np.nan))
    p_graze = np.clip(
        (noise.grazing_cos - np.nan_to_num(cos, nan=1.0)) / (noise.grazing_cos / 2), 0, 1
    )
    valid &= rng.random((h, w)) >= p_graze
    valid &= rng.random((h, w)) >= noise.dropout
    depth_mm = np.where(valid, np.round(fb / np.where(valid, dq, 1.0) * 1000.0), 0.0)
    return np.clip(depth_mm, 0, 65535).astype(np.uint16)
