"""The projector-ray lattice: its nodes, their spacing on the surface, and the clean-up
of step 4-5: spikes rejected, small holes filled, a confidence per node."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.projector import Projector


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


def fill_holes(
    s: FloatArray, max_nodes: int, blocked: BoolArray | None = None
) -> tuple[FloatArray, BoolArray]:
    """Fill NaN regions of at most ``max_nodes`` nodes that do not touch the border
    (nor a ``blocked`` node: a silhouette's, see :mod:`~adaproj_edge.geometry.depth.cuts`).

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
    if blocked is not None:
        small[np.unique(labels[blocked])] = False
    fill = small[labels]
    if not fill.any():
        return s, fill
    out = np.where(fill, np.nanmean(s), s)
    # Jacobi steps on the filled nodes alone: none is on the border, and their four
    # neighbours (above, below, left, right) are known or filled (a hole is a whole
    # 4-connected NaN region), so each becomes the plain mean of the four
    at = np.flatnonzero(fill)
    cols = s.shape[1]
    around = np.stack([at - cols, at + cols, at - 1, at + 1])
    flat = out.reshape(-1)
    for _ in range(4 * max_nodes + 20):
        flat[at] = flat[around].sum(axis=0) / 4
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


def supersampling(
    projector: Projector, shape: tuple[int, int], zs: FloatArray, settings: DepthSettings
) -> int:
    """How many times finer than ``shape`` to sample, so that nodes are at most
    ``smooth_m / 2`` apart on the surface (1 for fine lattices, at most 4)."""
    good = zs[np.isfinite(zs)]
    return supersampling_at(
        projector, shape, float(np.median(good)) if good.size else None, settings
    )


def supersampling_at(
    projector: Projector, shape: tuple[int, int], z_median: float | None, settings: DepthSettings
) -> int:
    """:func:`supersampling` for a surface at median depth ``z_median`` (None: 1.5 m)."""
    z = 1.5 if z_median is None else z_median
    k = np.ceil(node_spacing_m(projector, shape, z) / (settings.smooth_m / 2))
    return int(np.clip(k, 1, settings.max_supersample))


def dense_shape(projector: Projector, step: int = 4) -> tuple[int, int]:
    """Lattice shape with one node every ``step`` projector pixels."""
    return (projector.height - 1) // step + 1, (projector.width - 1) // step + 1
