"""Distortion of what the projector displays, as the device reports it.

Per small triangle of a ``step``-pixel sampling of the projector frame: J, the 3x2
Jacobian of the map content -> surface (from ``map_xy`` and the surface's points),
sigma1 >= sigma2 its singular values; angle error = sigma1 / sigma2 - 1, size =
sqrt(sigma1 sigma2), size inconsistency = std of log size. (The tests score warps with
their own implementation against analytic ground truth.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.surface import Surface


@dataclass(frozen=True)
class Quality:
    """Distortion figures of a warp over ``samples`` sample triangles.

    Attributes
    ----------
    angle_error : float
        Mean of sigma1 / sigma2 - 1 (0 for a conformal map).
    size_inconsistency : float
        Standard deviation of log sqrt(sigma1 sigma2).
    samples : int
        Sample triangles counted (NaN figures when 0).
    """

    angle_error: float  # mean of sigma1 / sigma2 - 1
    size_inconsistency: float  # std of log sqrt(sigma1 sigma2)
    samples: int

    def as_dict(self) -> dict[str, float]:
        """The figures as a JSON-ready dict."""
        return {
            "angle_error": self.angle_error,
            "size_inconsistency": self.size_inconsistency,
            "samples": self.samples,
        }


def triangle_distortion(
    map_xy: NDArray[np.float32], surface: Surface, step: int = 4
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Angle error (N,), log size (N,) and content centroid (N, 2) per sample triangle."""
    p = surface.projector
    ys = np.arange(0, p.height, step)
    xs = np.arange(0, p.width, step)
    uv = np.stack(np.meshgrid(xs, ys), axis=-1).astype(np.float64)
    c = map_xy[::step, ::step].astype(np.float64)
    X = surface.points_at(uv)
    angles, sizes, cents = [], [], []
    for (i1, j1), (i2, j2) in (((0, 1), (1, 1)), ((1, 1), (1, 0))):
        c0, x0 = c[:-1, :-1], X[:-1, :-1]
        c1 = c[i1 : i1 + c.shape[0] - 1, j1 : j1 + c.shape[1] - 1]
        c2 = c[i2 : i2 + c.shape[0] - 1, j2 : j2 + c.shape[1] - 1]
        x1 = X[i1 : i1 + X.shape[0] - 1, j1 : j1 + X.shape[1] - 1]
        x2 = X[i2 : i2 + X.shape[0] - 1, j2 : j2 + X.shape[1] - 1]
        dc = np.stack([c1 - c0, c2 - c0], axis=-1).reshape(-1, 2, 2)
        dx = np.stack([x1 - x0, x2 - x0], axis=-1).reshape(-1, 3, 2)
        det = dc[:, 0, 0] * dc[:, 1, 1] - dc[:, 0, 1] * dc[:, 1, 0]
        ok = np.isfinite(dc).all(axis=(1, 2)) & np.isfinite(dx).all(axis=(1, 2)) & (det > 0)
        sv = np.linalg.svd(dx[ok] @ np.linalg.inv(dc[ok]), compute_uv=False)
        angles.append(sv[:, 0] / sv[:, 1] - 1.0)
        sizes.append(0.5 * np.log(sv[:, 0] * sv[:, 1]))
        cents.append(((c0 + c1 + c2) / 3.0).reshape(-1, 2)[ok])
    return np.concatenate(angles), np.concatenate(sizes), np.concatenate(cents)


def summarise(angle: FloatArray, log_size: FloatArray) -> Quality:
    """The :class:`Quality` of per-triangle angle errors and log sizes, (N,) each."""
    if angle.size == 0:
        return Quality(float("nan"), float("nan"), 0)
    return Quality(float(np.mean(angle)), float(np.std(log_size)), int(angle.size))


def measure(
    map_xy: NDArray[np.float32],
    surface: Surface,
    salient: NDArray[np.bool_] | None = None,
    step: int = 4,
) -> tuple[Quality, Quality | None]:
    """Distortion over all displayed content and, given a (h, w) salient mask of the
    content, over the salient part."""
    angle, log_size, cent = triangle_distortion(map_xy, surface, step)
    overall = summarise(angle, log_size)
    if salient is None:
        return overall, None
    h, w = salient.shape
    x = np.clip(np.rint(cent[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(cent[:, 1]).astype(int), 0, h - 1)
    k = salient[y, x]
    return overall, summarise(angle[k], log_size[k])
