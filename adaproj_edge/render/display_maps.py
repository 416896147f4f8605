"""Display maps: what the renderer draws a warp with, built fast enough for a device.

The per-pixel surface map (:func:`~adaproj_edge.render.maps.map_from_warp`) costs about
a second on the board. The display maps are built instead at 1/``scale`` of the frame
by perspective-correct interpolation of the mesh (:class:`PixelWeights`: which triangle
each pixel lies in and its weights there, computed once per pose and shared by every
warp of that pose) and interpolated up to the frame inside the conversion to
``cv2.remap``'s fixed-point maps. On the analytic test surfaces this shows the same
distortion as the per-pixel map.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.render.frame import RemapMaps
from adaproj_edge.render.maps import PixelLayout, PixelWeights, map_from_warp
from adaproj_edge.warp.warpmap import Warp


def scaled_projector(projector: Projector, factor: int) -> Projector:
    """The projector frame at 1/``factor`` resolution (pixel centres at integers)."""
    s = 1.0 / factor
    S = np.array([[s, 0.0, 0.5 * s - 0.5], [0.0, s, 0.5 * s - 0.5], [0.0, 0.0, 1.0]])
    return Projector(S @ projector.K, projector.width // factor, projector.height // factor)


def _scaled_grid(grid_uv: FloatArray, factor: int) -> FloatArray:
    """Grid vertex pixel coordinates (R, C, 2) at 1/``factor`` of the frame."""
    out: FloatArray = (grid_uv + 0.5) / max(factor, 1) - 0.5
    return out


def small_layout(grid_uv: FloatArray, projector: Projector, factor: int) -> PixelLayout:
    """The pixel layout of the grid ``grid_uv`` (R, C, 2) at 1/``factor`` of the frame."""
    small = scaled_projector(projector, max(factor, 1))
    return PixelLayout.build(_scaled_grid(grid_uv, factor), small)


def small_weights(warp: Warp, factor: int, layout: PixelLayout | None = None) -> PixelWeights:
    """Pixel weights of ``warp``'s mesh (grid and vertex depths) at 1/``factor`` of the
    frame: one set per pose, shared by every warp of that mesh. ``layout``: the grid's
    layout at that resolution (:func:`small_layout`), when the caller keeps it."""
    small = scaled_projector(warp.projector, max(factor, 1))
    return PixelWeights.build(_scaled_grid(warp.grid_uv, factor), warp.depth, small, layout=layout)


def display_float_map(warp: Warp, factor: int) -> NDArray[np.float32]:
    """The (H, W, 2) content map of ``warp`` for the full frame, interpolated
    perspective-correctly at 1/``factor`` resolution and scaled up (NaN: black); what
    the display maps of ``factor`` draw, as floats (for scoring)."""
    p = warp.projector
    if factor <= 1:
        return map_from_warp(warp)
    m = small_weights(warp, factor).map(warp.image_xy, warp.content_size)
    # align pixel centres: full-res pixel x sits at (x + 0.5) / factor - 0.5 coarse
    big = cv2.resize(m, (p.width, p.height), interpolation=cv2.INTER_LINEAR)
    return np.asarray(big, dtype=np.float32)


class DisplayMapBuilder:
    """Builds the renderer's maps for the warps of one projector and one grid.

    Keeps what every warp shares: the grid's pixel layout at the reduced resolution and
    one full-resolution float buffer on the way to the fixed-point maps (a fresh 8 MB
    array per update costs page faults on every page).

    Parameters
    ----------
    projector : Projector
        The projector frame.
    grid_uv : (R, C, 2) float array
        The warp grid's vertices in projector pixels.
    scale : int
        Maps are built at 1/``scale`` of the frame and interpolated up (1: full size).
    """

    def __init__(self, projector: Projector, grid_uv: FloatArray, scale: int = 4) -> None:
        self.projector = projector
        self.scale = scale
        self._grid_uv = grid_uv
        self._layout = small_layout(grid_uv, projector, scale)
        self._scratch = np.empty((projector.height, projector.width, 2), np.float32)

    def pixel_weights(self, warp: Warp) -> PixelWeights:
        """The reduced-resolution pixel weights of ``warp``'s mesh (one set per pose:
        any warp of the same grid and vertex depths maps through them)."""
        same = warp.grid_uv.shape == self._grid_uv.shape and np.array_equal(
            warp.grid_uv, self._grid_uv
        )
        return small_weights(warp, self.scale, self._layout if same else None)

    def maps(self, warp: Warp, weights: PixelWeights | None = None) -> RemapMaps:
        """The renderer's maps of ``warp``, through ``weights`` (its pose's pixel
        weights, :meth:`pixel_weights`) when the caller keeps them."""
        w = weights if weights is not None else self.pixel_weights(warp)
        small = w.map(warp.image_xy, warp.content_size, clip=False)
        size = (warp.projector.width, warp.projector.height)
        return RemapMaps.upsampled(small, size, self._scratch)

    def float_map(self, warp: Warp) -> NDArray[np.float32]:
        """What the maps of ``warp`` draw, as a float map (H, W, 2), NaN where black."""
        return display_float_map(warp, self.scale)
