"""Warp mesh -> per-pixel map: the content coordinate each projector pixel shows.

Every pixel shows a weighted sum of a few grid vertices' content positions: the
corners of its grid triangle (``V0 + u (V1 - V0) + v (V2 - V0)``), and near an edge
the neighbouring triangle's too. The weights depend only on the surface and the grid,
never on where the vertices go in content space, so they are computed once per pose
(:class:`PixelWeights`) and any later warp of the same pose - a content-aware
refinement, new content - maps by a gather (:meth:`PixelWeights.map`).

How the weights are found:

* with the dense surface (:mod:`adaproj_edge.render.seams`): the pixel's own surface
  point X is projected orthogonally onto the plane of its 3D triangle. On a plane this
  is exact; on a curved developable surface the error is second order in the cell's
  curvature (it does not grow with the viewing angle, unlike any interpolation along
  the ray). In a triangle that a crease (a wall corner) runs through, X is first
  unfolded like the triangle itself (:mod:`adaproj_edge.geometry.creases`), so each
  side of the crease is exact too. Near an edge the places given by the two triangles
  that share it are blended, so the map is continuous across it; where the result
  would still turn a pixel over (at a curved crease), the perspective-correct map is
  blended in locally (:mod:`adaproj_edge.render.folds`) and the pixels counted.
* where X is unknown (or without a surface): perspective-correct interpolation with
  the vertex depths, ``(l_k / z_k) / sum_j (l_j / z_j)`` for pixel-space barycentrics
  ``l_k`` - exact over the 3D triangle the rays span, continuous, and fold-free
  wherever the mesh is.

Plain piecewise-linear interpolation in pixel space leaves a projective error of a few
percent per cell even on a tilted plane.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray, IntArray
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import grid_cells, grid_triangles
from adaproj_edge.render.folds import guard as fold_guard
from adaproj_edge.render.seams import surface_weights
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
    def build(cls, grid_uv: FloatArray, projector: Projector, step: int = 1) -> PixelLayout:
        """The layout of the grid with vertices at ``grid_uv`` (R, C, 2) in the frame of
        ``projector`` (of every ``step``-th pixel along x and y: (H/step, W/step))."""
        rows, cols = grid_uv.shape[:2]
        corners = grid_triangles(rows - 1, cols - 1)
        cx, fx = grid_cells(grid_uv[0, :, 0], projector.width, step)
        cy, fy = grid_cells(grid_uv[:, 0, 1], projector.height, step)
        cxx, cyy = np.meshgrid(cx, cy)
        fxx, fyy = np.meshgrid(fx, fy)
        upper = fxx >= fyy  # triangle (a, b, e), else (a, e, d)
        tri = 2 * (cyy * (cols - 1) + cxx) + (~upper).astype(np.intp)
        l1 = np.where(upper, fxx - fyy, fxx)
        l2 = np.where(upper, fyy, fyy - fxx)
        pixel_corners = np.moveaxis(corners[tri], -1, 0).astype(np.int32)
        return cls(tri, pixel_corners, 1.0 - l1 - l2, l1, l2)

    def onto_mesh(
        self, grid_uv: FloatArray, projector: Projector, depth: FloatArray, step: int = 1
    ) -> PixelLayout:
        """The layout with every pixel that lies on an edge or corner of a triangle with
        surface given to such a triangle.

        A pixel on a grid line (grid vertices sit on integer pixel centres) is given to
        the cell right of / below the line; where that cell has no surface and the one
        left of / above it has, the pixel lies on the mesh's outline and would show
        black: the outline's last column or row of pixels, where the content the mesh
        places there (up to its inscribed rectangle, :mod:`~adaproj_edge.warp.placement`)
        is lost. Likewise a pixel on a cell's diagonal is given to the upper triangle.
        ``depth`` (R, C): vertex depths, NaN without surface; ``step`` as in
        :meth:`build`. Returns ``self`` when no pixel moves.
        """
        rows, cols = grid_uv.shape[:2]
        has = np.isfinite(np.asarray(depth, dtype=np.float64).reshape(-1))
        ok: BoolArray = np.asarray(has[grid_triangles(rows - 1, cols - 1)].all(axis=1), dtype=bool)
        if ok.all() or not ok.any():
            return self
        cx, fx = grid_cells(grid_uv[0, :, 0], projector.width, step)
        cy, fy = grid_cells(grid_uv[:, 0, 1], projector.height, step)
        # only pixels on a grid line or a diagonal can lie on two triangles
        iy, ix = np.nonzero(
            (fx[None, :] == 0.0) | (fy[:, None] == 0.0) | (fx[None, :] == fy[:, None])
        )
        lost = ~ok[self.tri[iy, ix]]
        iy, ix = iy[lost], ix[lost]
        cx, fx, cy, fy = cx[ix], fx[ix], cy[iy], fy[iy]
        if iy.size == 0:
            return self
        tri, l1, l2 = self.tri.copy(), self.l1.copy(), self.l2.copy()
        corners, tris = self.corners.copy(), grid_triangles(rows - 1, cols - 1)
        todo = np.ones(iy.size, dtype=bool)
        for back_x, back_y, upper in itertools.product((0, 1), (0, 1), (True, False)):
            # the cell left of / above the line, the pixel on its far side (f = 1)
            bx = (fx == 0.0) & (cx > 0) if back_x else np.ones_like(todo)
            by = (fy == 0.0) & (cy > 0) if back_y else np.ones_like(todo)
            gx = np.where(back_x, 1.0, fx)
            gy = np.where(back_y, 1.0, fy)
            inside = (gx >= gy) if upper else (gx <= gy)
            t = 2 * ((cy - back_y) * (cols - 1) + cx - back_x) + (0 if upper else 1)
            hit = todo & bx & by & inside & ok[np.clip(t, 0, ok.size - 1)]
            if not hit.any():
                continue
            pix = (iy[hit], ix[hit])
            tri[pix] = t[hit]
            corners[:, pix[0], pix[1]] = tris[t[hit]].T
            l1[pix] = np.where(upper, gx - gy, gx)[hit]
            l2[pix] = np.where(upper, gy, gy - gx)[hit]
            todo &= ~hit
        if todo.all():
            return self
        return PixelLayout(tri, corners, 1.0 - l1 - l2, l1, l2)


@dataclass(frozen=True)
class PixelWeights:
    """For every projector pixel: weights on a few grid vertices (its triangle's corners,
    and near an edge the neighbour's far corner too) that place it in content space.

    Attributes
    ----------
    corners : (K, H, W) int32 grid vertex indices (K = 3: the corners of each pixel's
        triangle in ``grid_triangles`` order; K = 6 with a surface, see
        :mod:`adaproj_edge.render.seams`).
    weights : (K, H, W) float32 weights on them; NaN where the pixel's triangle has a
        corner without surface (it shows black).
    fallback : (3, H, W) float32 or None
        With a surface, the perspective-correct weights on the first three corners,
        blended in where the surface-based map would fold (:mod:`~adaproj_edge.render.folds`).
    """

    corners: NDArray[np.int32]
    weights: NDArray[np.float32]
    fallback: NDArray[np.float32] | None = None

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
        if depth is not None:
            layout = layout.onto_mesh(grid_uv, projector, depth)
        c0, c1, c2 = layout.corners
        if depth is None:
            w = np.stack([layout.l0, layout.l1, layout.l2])
        else:
            # perspective-correct weights of the triangle's corners (a, b|e, e|d)
            inv_z = 1.0 / depth.reshape(-1)  # NaN without surface: the pixel shows black
            w = np.stack([layout.l0 * inv_z[c0], layout.l1 * inv_z[c1], layout.l2 * inv_z[c2]])
            w /= w.sum(axis=0)
        if surface is None or depth is None:
            return cls(layout.corners, w.astype(np.float32))
        bary = np.stack([layout.l0, layout.l1, layout.l2])
        corners, ws = surface_weights(grid_uv, depth, projector, surface, layout.tri, bary)
        # where the pixel's own surface point is unknown: the perspective-correct weights
        unknown = ~np.isfinite(ws[0])
        ws[:3, unknown] = w[:, unknown]
        ws[3:, unknown] = 0.0
        return cls(corners, ws.astype(np.float32), w.astype(np.float32))

    def _gather(
        self, verts: NDArray[np.float32], corners: NDArray[np.int32], weights: NDArray[np.float32]
    ) -> NDArray[np.float32]:
        out = np.zeros((*weights.shape[1:], 2), dtype=np.float32)
        for k in range(weights.shape[0]):
            for c in range(2):
                out[..., c] += weights[k] * verts[corners[k], c]
        return out

    def checked_map(
        self, image_xy: FloatArray, content_size: tuple[int, int], clip: bool = True
    ) -> tuple[NDArray[np.float32], int]:
        """:meth:`map`, and how many pixels took part of their value from the
        perspective-correct fallback because the surface-based map folds there."""
        verts = np.asarray(image_xy, dtype=np.float32).reshape(-1, 2)
        out = self._gather(verts, self.corners, self.weights)
        fell_back = 0
        if self.fallback is not None:
            plain = self._gather(verts, self.corners[:3], self.fallback)
            out, fell_back = fold_guard(out, plain)
        if not clip:
            return out, fell_back
        w, h = content_size
        finite = np.isfinite(out).all(axis=2)
        with np.errstate(invalid="ignore"):
            inside = (
                finite
                & (out[..., 0] >= -0.5)
                & (out[..., 0] <= w - 0.5)
                & (out[..., 1] >= -0.5)
                & (out[..., 1] <= h - 0.5)
            )
        # the ring of pixels just past the content's border stays (the renderer shows
        # it black, anti-aliased): where the content is shown smaller than the pixels
        # its outermost columns lie between the last pixel in and the first one out
        ring = np.asarray(cv2.dilate(inside.astype(np.uint8), np.ones((3, 3), np.uint8))) > 0
        out[~(finite & ring)] = np.nan
        return out, fell_back

    def map(
        self, image_xy: FloatArray, content_size: tuple[int, int], clip: bool = True
    ) -> NDArray[np.float32]:
        """The (H, W, 2) float32 map for vertex content coordinates ``image_xy`` (R, C, 2);
        NaN where the pixel shows black: no surface, or (``clip``) outside the content
        by more than one pixel (the ring just outside stays, for the renderer's
        anti-aliased edge). Without ``clip`` every coordinate outside the content is
        kept (the renderer's border turns them black)."""
        return self.checked_map(image_xy, content_size, clip)[0]


def map_from_warp(
    warp: Warp, surface: Surface | None = None, weights: PixelWeights | None = None
) -> NDArray[np.float32]:
    """The (H, W, 2) float32 map of content coordinates; NaN where the pixel shows black
    (no surface under its triangle, or outside the content). With a surface, the
    number of pixels where the fold guard fell back is recorded in
    ``warp.meta["display_fallback_pixels"]``. ``weights``: the
    :meth:`PixelWeights.build` of ``warp``'s grid, vertex depths, projector and
    ``surface``, when the caller keeps them (every warp of that mesh shares them)."""
    if weights is None:
        weights = PixelWeights.build(warp.grid_uv, warp.depth, warp.projector, surface)
    out, fell_back = weights.checked_map(warp.image_xy, warp.content_size)
    if surface is not None:
        warp.meta["display_fallback_pixels"] = fell_back
    return out
