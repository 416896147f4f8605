"""One projection: surface + content + settings -> warp, per-pixel map and frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.frame import RemapMaps, render_frame
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Warp


@dataclass(frozen=True)
class Projection:
    warp: Warp
    map_xy: NDArray[np.float32]
    maps: RemapMaps
    frame: NDArray[np.uint8]


def project(
    surface: Surface,
    content: NDArray[np.uint8],
    content_map: ContentMap | NDArray[np.floating] | None,
    settings: WarpSettings,
) -> Projection:
    """Compute the warp for ``content`` (h, w[, 3]) on ``surface`` and render its frame."""
    h, w = content.shape[:2]
    return show(surface, content, compute_warp(surface, (w, h), content_map, settings))


def show(surface: Surface, content: NDArray[np.uint8], warp: Warp) -> Projection:
    """Render ``content`` (h, w[, 3]) through ``warp`` (made for ``surface``) with the
    per-pixel surface map (a standard warp maps the frame as it is)."""
    standard = warp.meta.get("mode") == "standard"
    map_xy = map_from_warp(warp, None if standard else surface)
    warp.map_xy = map_xy
    maps = RemapMaps.from_map(map_xy)
    return Projection(warp, map_xy, maps, render_frame(content, maps))
