"""Where content points are shown: a few points of the content followed into the
projector frame through a warp (its mesh inverted), to score how the picture moves and
to carry it smoothly from one frame to the next."""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.triangles import carry_through_triangles, grid_triangles
from adaproj_edge.warp.warpmap import Warp

GRID = 5
PAIR = 0.2  # the vertical pair: the centre +- this share of the content's height
BOX_SLACK = 1e-6  # content px: a point on a triangle's edge is in its box


def content_points(size: tuple[int, int]) -> FloatArray:
    """Content pixels (GRID * GRID + 2, 2): a grid from 10 % to 90 % of the content, then
    the vertical pair (top, bottom) at its centre."""
    w, h = size
    xs = np.linspace(0.1, 0.9, GRID) * (w - 1)
    ys = np.linspace(0.1, 0.9, GRID) * (h - 1)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    cx, cy = (w - 1) / 2, (h - 1) / 2
    pair = np.array([[cx, cy - PAIR * (h - 1)], [cx, cy + PAIR * (h - 1)]])
    out: FloatArray = np.vstack([grid, pair])
    return out


def frame_pixels(warp: Warp, xy: FloatArray) -> FloatArray:
    """The projector pixels (N, 2) that show content pixels ``xy`` (N, 2) through
    ``warp`` (its mesh inverted, each triangle linear), NaN where none does."""
    rows, cols = warp.image_xy.shape[:2]
    tris = grid_triangles(rows - 1, cols - 1)
    q = warp.image_xy.reshape(-1, 2)[tris]  # (T, 3, 2) content corners
    g = warp.grid_uv.reshape(-1, 2)[tris]
    return carry_through_triangles(q, g, xy, BOX_SLACK)
