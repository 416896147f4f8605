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
    a, b, c = q[:, 0], q[:, 1], q[:, 2]
    v0, v1 = b - a, c - a
    det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]  # (T,)
    d = xy[None, :, :] - a[:, None, :]  # (T, N, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (d[..., 0] * v1[:, None, 1] - d[..., 1] * v1[:, None, 0]) / det[:, None]
        t = (v0[:, None, 0] * d[..., 1] - v0[:, None, 1] * d[..., 0]) / det[:, None]
    inside = (s >= -1e-9) & (t >= -1e-9) & (s + t <= 1 + 1e-9) & np.isfinite(s + t)
    k = np.argmax(inside, axis=0)  # the first triangle holding each point
    n = np.arange(len(xy))
    gk = g[k]  # (N, 3, 2)
    sk, tk = s[k, n][:, None], t[k, n][:, None]
    out: FloatArray = gk[:, 0] + sk * (gk[:, 1] - gk[:, 0]) + tk * (gk[:, 2] - gk[:, 0])
    out[~inside[k, n]] = np.nan
    return out
