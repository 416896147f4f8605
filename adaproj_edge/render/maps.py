"""Warp mesh -> per-pixel map: the content coordinate each projector pixel shows.

Every pixel lies in one grid triangle and shows ``V0 + u (V1 - V0) + v (V2 - V0)`` of
that triangle's content-space corners. The weights (u, v) depend only on the surface
and the grid, never on where the corners go in content space, so they are computed
once per pose (:class:`PixelWeights`) and any later warp of the same pose — a
content-aware refinement, new content — maps by a gather (:meth:`PixelWeights.map`).

How (u, v) are found:

* with the dense surface: the pixel's own surface point X is projected orthogonally
  onto the plane of its 3D triangle. On a plane this is exact; on a curved developable
  surface the error is second order in the cell's curvature (it does not grow with the
  viewing angle, unlike any interpolation along the ray). In a triangle that a crease
  (a wall corner) runs through, X is first unfolded like the triangle itself
  (:mod:`adaproj_edge.geometry.creases`), so each side of the crease is exact too.
* where X is unknown (or without a surface): perspective-correct interpolation with
  the vertex depths, ``(l_k / z_k) / sum_j (l_j / z_j)`` for pixel-space barycentrics
  ``l_k`` — exact over the 3D triangle the rays span.

Plain piecewise-linear interpolation in pixel space leaves a projective error of a few
percent per cell even on a tilted plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.creases import unfold_creases
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import grid_cells, grid_triangles
from adaproj_edge.warp.warpmap import Warp


@dataclass(frozen=True)
class PixelLayout:
    """Which grid triangle each projector pixel falls in, and its pixel-space barycentric
    weights there: fixed by the grid and the frame alone, so computed once per grid.

    Attributes
    ----------
    tri : (H, W) index of the pixel's triangle (``grid_triangles`` order).
    corners : (3, H, W) int32 grid vertex indices of the triangle's corners.
    l0, l1, l2 : (H, W) pixel-space barycentric weights of the corners.
    """

    tri: IntArray
    corners: NDArray[np.int32]
    l0: FloatArray
    l1: FloatArray
    l2: FloatArray

    @classmethod
    def build(cls, grid_uv: FloatArray, projector: Projector) -> PixelLayout:
        """The layout of the grid with vertices at ``grid_uv`` (R, C, 2) in the frame of
        ``projector``."""
        rows, cols = grid_uv.shape[:2]
        corners = grid_triangles(rows - 1, cols - 1)
        cx, fx = grid_cells(grid_uv[0, :, 0], projector.width)
        cy, fy = grid_cells(grid_uv[:, 0, 1], projector.height)
        cxx, cyy = np.meshgrid(cx, cy)
        fxx, fyy = np.meshgrid(fx, fy)
        upper = fxx >= fyy  # triangle (a, b, e), else (a, e, d)
        tri = 2 * (cyy * (cols - 1) + cxx) + (~upper).astype(np.intp)
        l1 = np.where(upper, fxx - fyy, fxx)
        l2 = np.where(upper, fyy, fyy - fxx)
        pixel_corners = np.moveaxis(corners[tri], -1, 0).astype(np.int32)
        return cls(tri, pixel_corners, 1.0 - l1 - l2, l1, l2)


@dataclass(frozen=True)
class PixelWeights:
    """For every projector pixel: its grid triangle and weights (u, v) on its corners.

    Attributes
    ----------
    corners : (3, H, W) int32 grid vertex indices of the corners of each pixel's
        triangle (``grid_triangles`` order).
    u, v : (H, W) float32 weights of the triangle's corners 1 and 2; NaN where the
        pixel's triangle has a corner without surface (it shows black).
    """

    corners: NDArray[np.int32]
    u: NDArray[np.float32]
    v: NDArray[np.float32]

    @classmethod
    def build(
        cls,
        grid_uv: FloatArray,
        depth: FloatArray | None,
        projector: Projector,
        surface: Surface | None = None,
        layout: PixelLayout | None = None,
    ) -> PixelWeights:
        """Weights for the grid ``grid_uv`` (R, C, 2) with vertex depths ``depth`` (R, C)
        (NaN where no surface; None: plain pixel-space interpolation). ``layout``: the
        grid's :class:`PixelLayout`, when the caller keeps it."""
        if layout is None:
            layout = PixelLayout.build(grid_uv, projector)
        c0, c1, c2 = layout.corners
        if depth is None:
            u, v = layout.l1, layout.l2
        else:
            # perspective-correct weights of the triangle's corners (a, b|e, e|d)
            inv_z = 1.0 / depth.reshape(-1)  # NaN without surface: the pixel shows black
            w0 = layout.l0 * inv_z[c0]
            w1 = layout.l1 * inv_z[c1]
            w2 = layout.l2 * inv_z[c2]
            total = w0 + w1 + w2
            u, v = w1 / total, w2 / total
        if surface is not None and depth is not None:
            rows, cols = grid_uv.shape[:2]
            corners = grid_triangles(rows - 1, cols - 1)
            uo, vo = _surface_weights(grid_uv, depth, projector, corners, layout.tri, surface)
            use = np.isfinite(uo) & np.isfinite(u)
            u = np.where(use, uo, u)
            v = np.where(use, vo, v)
        return cls(layout.corners, u.astype(np.float32), v.astype(np.float32))

    def map(
        self, image_xy: FloatArray, content_size: tuple[int, int], clip: bool = True
    ) -> NDArray[np.float32]:
        """The (H, W, 2) float32 map for vertex content coordinates ``image_xy`` (R, C, 2);
        NaN where the pixel shows black: no surface, or (``clip``) outside the content.
        Without ``clip`` coordinates outside the content are kept (the renderer's
        border turns them black, with an anti-aliased edge)."""
        verts = np.asarray(image_xy, dtype=np.float32).reshape(-1, 2)
        c0, c1, c2 = self.corners
        out = np.empty((*self.u.shape, 2), dtype=np.float32)
        for k in range(2):
            vk = verts[:, k]
            p0 = vk[c0]
            out[..., k] = p0 + self.u * (vk[c1] - p0) + self.v * (vk[c2] - p0)
        if not clip:
            return out
        w, h = content_size
        with np.errstate(invalid="ignore"):
            outside = (
                ~np.isfinite(out).all(axis=2)
                | (out[..., 0] < -0.5)
                | (out[..., 0] > w - 0.5)
                | (out[..., 1] < -0.5)
                | (out[..., 1] > h - 0.5)
            )
        out[outside] = np.nan
        return out


def _surface_weights(
    grid_uv: FloatArray,
    depth: FloatArray,
    projector: Projector,
    corners: IntArray,
    tri: IntArray,
    surface: Surface,
) -> tuple[FloatArray, FloatArray]:
    """(u, v) of each pixel's own surface point, unfolded, projected on its triangle."""
    P = (projector.rays(grid_uv) * depth[..., None]).reshape(-1, 3)
    unfolding = unfold_creases(surface, grid_uv.reshape(-1, 2)[corners], corners, P)
    pts = unfolding.points
    origin = pts[:, 0]
    e1 = pts[:, 1] - origin
    e2 = pts[:, 2] - origin
    with np.errstate(invalid="ignore", divide="ignore"):
        g11 = np.sum(e1 * e1, axis=1)[:, None]
        g12 = np.sum(e1 * e2, axis=1)[:, None]
        g22 = np.sum(e2 * e2, axis=1)[:, None]
        det = g11 * g22 - g12 * g12
        # [u v] = G^-1 [e1 e2]^T (X - origin): one 2x3 matrix per triangle
        bary = np.stack([g22 * e1 - g12 * e2, g11 * e2 - g12 * e1], axis=1) / det[:, :, None]
    offset = np.einsum("tij,tj->ti", bary, origin)
    X = unfolding.unfold_points(tri, surface.dense().points.astype(np.float64))
    out = []
    for i in range(2):
        m = bary[:, i, :][tri]
        out.append(
            m[..., 0] * X[..., 0] + m[..., 1] * X[..., 1] + m[..., 2] * X[..., 2] - offset[tri, i]
        )
    return out[0], out[1]


def map_from_warp(warp: Warp, surface: Surface | None = None) -> NDArray[np.float32]:
    """The (H, W, 2) float32 map of content coordinates; NaN where the pixel shows black
    (no surface under its triangle, or outside the content)."""
    weights = PixelWeights.build(warp.grid_uv, warp.depth, warp.projector, surface)
    return weights.map(warp.image_xy, warp.content_size)
