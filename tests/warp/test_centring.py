"""The picture sits in the middle of the lit surface (issue 12, item 2).

Content whose aspect is not the frame's used to be placed against one edge in the
``conformal`` and ``content`` modes (a square picture on a flat wall filled columns
3-801 of 1280). Scored here without the engine: the surface is ray-cast from every
projector pixel (:mod:`adaproj_edge.geometry.analytic`), flattened exactly (a plane is
its own flattening, a vertical cylinder unrolls to arc length and height), and the
area centroid of what shows the content is compared with that of everything lit.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from adaproj_edge.geometry.analytic import Cylinder, get_surface, simulate_surface
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp

NEAR_CENTRE = 0.03  # offset / sqrt(lit area) a centred picture may have


def _flat(name: str, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Exact flattening (H, W, 2 or 3) of the analytic surface's points (H, W, 3)."""
    shape = get_surface(name)
    if isinstance(shape, Cylinder):
        angle = np.arctan2(points[..., 0] - shape.cx, shape.cz - points[..., 2])
        return np.stack([shape.r * angle, points[..., 1]], axis=-1)
    return points  # a plane: distances on it are distances in space


def _offset(name: str, mode: str, size: tuple[int, int]) -> tuple[float, tuple[int, int]]:
    """Distance between the shown content's centroid and the lit region's, over the
    square root of the lit area; and the columns the content spans."""
    s = simulate_surface(name, step=4)
    points = s.dense().points.astype(np.float64)
    # each pixel's surface area: the cross product of its neighbours' differences
    area = np.linalg.norm(
        np.cross(np.gradient(points, axis=1), np.gradient(points, axis=0)), axis=2
    )
    lit = np.isfinite(area)
    area = np.where(lit, area, 0.0)
    flat = np.where(lit[..., None], _flat(name, points), 0.0)
    warp = compute_warp(s, size, None, WarpSettings(mode=mode))  # type: ignore[arg-type]
    shown = np.isfinite(map_from_warp(warp)).all(axis=2) & lit
    shown_area = np.where(shown, area, 0.0)

    def centroid(a: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = (a[..., None] * flat).sum(axis=(0, 1)) / a.sum()
        return out

    offset = float(np.linalg.norm(centroid(shown_area) - centroid(area)) / np.sqrt(area.sum()))
    cols = np.flatnonzero(shown.any(axis=0))
    return offset, (int(cols[0]), int(cols[-1]))


@pytest.mark.parametrize("size", [(512, 512), (400, 300)])
@pytest.mark.parametrize("mode", ["conformal", "content"])
@pytest.mark.parametrize("name", ["plane", "tilted", "cylinder-convex"])
def test_the_picture_is_centred_on_the_lit_surface(
    name: str, mode: str, size: tuple[int, int]
) -> None:
    offset, cols = _offset(name, mode, size)
    assert offset <= NEAR_CENTRE, (offset, cols)


def test_a_square_picture_on_a_flat_wall_sits_where_a_plain_projector_puts_it() -> None:
    _, plain = _offset("plane", "standard", (512, 512))
    _, ours = _offset("plane", "conformal", (512, 512))
    assert abs(ours[0] - plain[0]) <= 2 and abs(ours[1] - plain[1]) <= 2, (ours, plain)
