"""Warp mesh -> per-pixel map: the content coordinate each projector pixel shows.

Two ways to fill the inside of a grid triangle:

* ``surface`` given (the dense point map): the pixel's own surface point X is projected
  orthogonally onto the plane of its 3D triangle and carried to content space by the
  triangle's affine map. On a plane this is exact; on a curved developable surface the
  error is second order in the cell's curvature (it does not grow with the viewing
  angle, unlike any interpolation along the ray). Where X lies far from its own
  triangle's plane - a crease, such as a wall corner, running through the cell - the
  plane of a neighbouring triangle that X lies on is used instead, so each side of the
  crease gets its own wall's exact map.
* no surface: perspective-correct interpolation with the vertex depths,
  ``(l_k / z_k) / sum_j (l_j / z_j)`` for pixel-space barycentrics ``l_k`` - exact
  over the 3D triangle the rays span.

Plain piecewise-linear interpolation in pixel space leaves a projective error of a few
percent per cell even on a tilted plane.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.geometry.creases import unfold_creases
from adaproj_edge.geometry.projector import FloatArray
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import grid_triangles
from adaproj_edge.warp.mesh import Warp

IntArray = NDArray[np.intp]


def _cells(positions: FloatArray, n_pixels: int) -> tuple[IntArray, FloatArray]:
    """Cell index and fraction within it for every pixel coordinate 0..n_pixels-1."""
    x = np.arange(n_pixels, dtype=np.float64)
    c = np.clip(np.searchsorted(positions, x, side="right") - 1, 0, positions.size - 2)
    f = (x - positions[c]) / (positions[c + 1] - positions[c])
    return c, f


class _PixelCells:
    """Which cell and which of its two triangles each pixel lies in."""

    def __init__(self, warp: Warp) -> None:
        proj = warp.projector
        self.rows, self.cols = warp.grid_uv.shape[:2]
        cx, fx = _cells(warp.grid_uv[0, :, 0], proj.width)
        cy, fy = _cells(warp.grid_uv[:, 0, 1], proj.height)
        self.cx, self.cy = np.meshgrid(cx, cy)
        self.fx, self.fy = np.meshgrid(fx, fy)
        self.upper = self.fx >= self.fy  # triangle (a, b, e), else (a, e, d)
        # triangle index as numbered by grid_triangles: 2 * cell + (0 upper, 1 lower)
        self.tri = 2 * (self.cy * (self.cols - 1) + self.cx) + (~self.upper).astype(np.intp)


def map_from_warp(warp: Warp, surface: Surface | None = None) -> NDArray[np.float32]:
    """The (H, W, 2) float32 map of content coordinates; NaN where the pixel shows black
    (no surface under its triangle, or outside the content)."""
    cells = _PixelCells(warp)
    out = _perspective(warp, cells)
    if surface is not None:
        X = surface.dense().points.astype(np.float64)
        ortho = _TrianglePlanes(warp, surface).to_content(cells.tri, X)
        use = np.isfinite(ortho).all(axis=2) & np.isfinite(out).all(axis=2)
        out[use] = ortho[use]
    w, h = warp.content_size
    outside = (
        ~np.isfinite(out).all(axis=2)
        | (out[..., 0] < -0.5)
        | (out[..., 0] > w - 0.5)
        | (out[..., 1] < -0.5)
        | (out[..., 1] > h - 0.5)
    )
    out[outside] = np.nan
    return out.astype(np.float32)


def _perspective(warp: Warp, cells: _PixelCells) -> FloatArray:
    cols = cells.cols
    a = cells.cy * cols + cells.cx
    b, d = a + 1, a + cols
    e = d + 1
    up, fx, fy = cells.upper, cells.fx, cells.fy
    la = np.where(up, 1.0 - fx, 1.0 - fy)
    lb = np.where(up, fx - fy, 0.0)
    ld = np.where(up, 0.0, fy - fx)
    le = np.where(up, fy, fx)
    if warp.depth is not None:
        # a vertex without surface gets weight 0, not NaN: it may be the one vertex of
        # the cell that is not in the pixel's triangle
        inv_z = np.nan_to_num(1.0 / warp.depth.reshape(-1), nan=0.0)
    else:
        inv_z = np.ones(cells.rows * cols)
    wa, wb, wd, we = la * inv_z[a], lb * inv_z[b], ld * inv_z[d], le * inv_z[e]
    total = wa + wb + wd + we
    v = warp.image_xy.reshape(-1, 2)
    out = np.empty((*a.shape, 2))
    for k in range(2):
        vk = v[:, k]
        # a zero weight must not let a NaN vertex of the other triangle through
        acc = wa * vk[a] + np.where(lb > 0, wb * vk[b], 0.0) + np.where(ld > 0, wd * vk[d], 0.0)
        out[..., k] = (acc + we * vk[e]) / total
    return out


class _TrianglePlanes:
    """Per grid triangle: its (unfolded) plane and the affine map from it to content."""

    def __init__(self, warp: Warp, surface: Surface) -> None:
        rows, cols = warp.grid_uv.shape[:2]
        tris = grid_triangles(rows - 1, cols - 1)
        if warp.depth is None:
            raise ValueError("a surface map needs the warp's vertex depths")
        P = (warp.projector.rays(warp.grid_uv) * warp.depth[..., None]).reshape(-1, 3)
        self.unfolding = unfold_creases(surface, warp.grid_uv.reshape(-1, 2)[tris], tris, P)
        corners = self.unfolding.points
        V = warp.image_xy.reshape(-1, 2)
        origin = corners[:, 0]
        e1 = corners[:, 1] - origin
        e2 = corners[:, 2] - origin
        with np.errstate(invalid="ignore", divide="ignore"):
            g11 = np.sum(e1 * e1, axis=1)[:, None]
            g12 = np.sum(e1 * e2, axis=1)[:, None]
            g22 = np.sum(e2 * e2, axis=1)[:, None]
            det = g11 * g22 - g12 * g12
            # barycentric (u, v) of X's projection: [u v] = G^-1 [e1 e2]^T (X - origin)
            bary = np.stack([g22 * e1 - g12 * e2, g11 * e2 - g12 * e1], axis=1) / det[:, :, None]
        v0 = V[tris[:, 0]]
        d = np.stack([V[tris[:, 1]] - v0, V[tris[:, 2]] - v0], axis=2)  # (T, 2, 2)
        # content = A X + b, one affine map per triangle
        self.A = np.einsum("tij,tjk->tik", d, bary)  # (T, 2, 3)
        self.b = v0 - np.einsum("tik,tk->ti", self.A, origin)

    def to_content(self, t: IntArray, X: FloatArray) -> FloatArray:
        """Content coordinates of surface points ``X`` (..., 3) in triangles ``t`` (...):
        unfolded when the triangle has a crease, then projected orthogonally onto the
        triangle's plane and carried by its affine map."""
        Xu = self.unfolding.unfold_points(t, X)
        out = np.empty((*t.shape, 2))
        for i in range(2):
            a = self.A[:, i, :][t]  # (..., 3)
            out[..., i] = (
                a[..., 0] * Xu[..., 0] + a[..., 1] * Xu[..., 1] + a[..., 2] * Xu[..., 2]
            ) + self.b[t, i]
        return out
