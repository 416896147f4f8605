"""Where content points are shown: a few points of the content followed into the
projector frame through a warp (its mesh inverted), to score how the picture moves and
to carry it smoothly from one frame to the next."""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.triangles import grid_triangles
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
    out: FloatArray = np.full((len(xy), 2), np.nan)
    # the pairs whose triangle's box holds the point (a NaN corner holds none), in
    # triangle order; then barycentric coordinates for those pairs alone
    c0, c1, c2 = q[:, 0], q[:, 1], q[:, 2]  # (three corners: not a slow reduce over 3)
    lo = np.minimum(np.minimum(c0, c1), c2) - BOX_SLACK  # (T, 2); NaN propagates
    hi = np.maximum(np.maximum(c0, c1), c2) + BOX_SLACK
    near = (
        (xy[None, :, 0] >= lo[:, None, 0])
        & (xy[None, :, 0] <= hi[:, None, 0])
        & (xy[None, :, 1] >= lo[:, None, 1])
        & (xy[None, :, 1] <= hi[:, None, 1])
    )
    ti, ni = np.nonzero(near)
    a = c0[ti]
    v0, v1 = c1[ti] - a, c2[ti] - a
    det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    d = xy[ni] - a
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (d[:, 0] * v1[:, 1] - d[:, 1] * v1[:, 0]) / det
        t = (v0[:, 0] * d[:, 1] - v0[:, 1] * d[:, 0]) / det
    inside = (s >= -1e-9) & (t >= -1e-9) & (s + t <= 1 + 1e-9) & np.isfinite(s + t)
    # the first triangle holding each point
    points, first = np.unique(ni[inside], return_index=True)
    k = np.flatnonzero(inside)[first]
    gk = g[ti[k]]  # (M, 3, 2)
    sk, tk = s[k, None], t[k, None]
    out[points] = gk[:, 0] + sk * (gk[:, 1] - gk[:, 0]) + tk * (gk[:, 2] - gk[:, 0])
    return out
