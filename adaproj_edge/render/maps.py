"""Warp mesh -> per-pixel map: the content coordinate each projector pixel shows.

Inside each grid triangle the content coordinate is interpolated perspective-correctly:
with pixel-space barycentrics ``l_k`` and vertex depths ``z_k`` the weights are
``(l_k / z_k) / sum_j (l_j / z_j)``, which is exact interpolation over the 3D triangle
the rays span (the same rule GPUs use). On a plane the warp is therefore exact at every
pixel, not only at the vertices; plain piecewise-linear interpolation leaves a
projective error of a few percent per cell.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.geometry.projector import FloatArray
from adaproj_edge.warp.mesh import Warp


def _cells(positions: FloatArray, n_pixels: int) -> tuple[NDArray[np.intp], FloatArray]:
    """Cell index and fraction within it for every pixel coordinate 0..n_pixels-1."""
    x = np.arange(n_pixels, dtype=np.float64)
    c = np.clip(np.searchsorted(positions, x, side="right") - 1, 0, positions.size - 2)
    f = (x - positions[c]) / (positions[c + 1] - positions[c])
    return c, f


def map_from_warp(warp: Warp, perspective: bool = True) -> NDArray[np.float32]:
    """The (H, W, 2) float32 map of content coordinates; NaN where the pixel shows black
    (no surface under its triangle, or outside the content)."""
    proj = warp.projector
    rows, cols = warp.grid_uv.shape[:2]
    xs = warp.grid_uv[0, :, 0]
    ys = warp.grid_uv[:, 0, 1]
    cx, fx = _cells(xs, proj.width)
    cy, fy = _cells(ys, proj.height)
    cxx, cyy = np.meshgrid(cx, cy)
    fxx, fyy = np.meshgrid(fx, fy)
    a = cyy * cols + cxx
    b = a + 1
    d = a + cols
    e = d + 1
    upper = fxx >= fyy  # triangle (a, b, e), else (a, e, d)
    la = np.where(upper, 1.0 - fxx, 1.0 - fyy)
    lb = np.where(upper, fxx - fyy, 0.0)
    ld = np.where(upper, 0.0, fyy - fxx)
    le = np.where(upper, fyy, fxx)
    v = warp.image_xy.reshape(-1, 2)
    if perspective and warp.depth is not None:
        inv_z = 1.0 / warp.depth.reshape(-1)
    else:
        inv_z = np.ones(rows * cols)
    wa, wb, wd, we = la * inv_z[a], lb * inv_z[b], ld * inv_z[d], le * inv_z[e]
    total = wa + wb + wd + we
    out = np.empty((proj.height, proj.width, 2), dtype=np.float32)
    for k in range(2):
        vk = v[:, k]
        # a zero weight must not let a NaN vertex of the other triangle through
        acc = wa * vk[a] + np.where(lb > 0, wb * vk[b], 0.0) + np.where(ld > 0, wd * vk[d], 0.0)
        acc = acc + we * vk[e]
        out[..., k] = acc / total
    w, h = warp.content_size
    outside = (
        ~np.isfinite(out).all(axis=2)
        | (out[..., 0] < -0.5)
        | (out[..., 0] > w - 0.5)
        | (out[..., 1] < -0.5)
        | (out[..., 1] > h - 0.5)
    )
    out[outside] = np.nan
    return out
