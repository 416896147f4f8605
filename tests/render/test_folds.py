"""Seams and folds of the per-pixel map: continuous across the mesh's edges, fold-free
where it is displayed, and a fallback that is local and counted."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.triangles import grid_triangles
from adaproj_edge.render.folds import fold_mask, guard
from adaproj_edge.render.maps import PixelWeights
from adaproj_edge.render.seams import grid_neighbours
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid


def affine_map(h: int = 60, w: int = 90) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    return np.stack([0.5 * xx + 0.1 * yy + 3.0, -0.2 * xx + 0.7 * yy + 1.0], axis=-1)


def test_an_orientation_keeping_map_has_no_folds() -> None:
    m = affine_map()
    assert not fold_mask(m).any()
    out, n = guard(m, m)
    assert n == 0 and out is m


def test_a_reversed_patch_is_found_and_smoothed_away_locally() -> None:
    m = affine_map()
    fold = m.copy()
    # push one pixel back past its neighbour along x: the map turns over there
    fold[30, 40, 0] = m[30, 38, 0]
    bad = fold_mask(fold)
    assert bad.any() and bad.sum() < 10
    out, n = guard(fold, m)
    assert not fold_mask(out).any()
    assert 0 < n < 0.05 * m.shape[0] * m.shape[1]  # local, and counted
    far = np.ones(m.shape[:2], dtype=bool)
    far[20:41, 30:51] = False
    np.testing.assert_array_equal(out[far], fold[far])  # untouched away from it


def test_smoothing_a_fold_next_to_the_outline_keeps_the_outline() -> None:
    """A fold against the map's outline (the frame's edge, a silhouette; issue 13: a
    cylinder on a floor, its crease through the frame's edge): the smoothing fits the
    map around it, and an affine map's outline stays where it was. A mean of the known
    pixels (all on one side) pulled the outline inward by several pixels, and the
    content placed up to it was not shown."""
    m = affine_map()
    m[:, 60:] = np.nan  # the outline: column 59
    fold = m.copy()
    fold[30, 57, 0] = m[30, 55, 0]
    assert fold_mask(fold).any()
    out, n = guard(fold, m)
    assert not fold_mask(out).any() and 0 < n < 0.05 * m.shape[0] * m.shape[1]
    assert np.isnan(out[:, 60:]).all()
    # the affine map is the ground truth; the outline's column within 0.05 px of it
    np.testing.assert_allclose(out[:, 59], m[:, 59], atol=0.05)


def test_not_shown_pixels_are_no_folds() -> None:
    m = affine_map()
    m[:, :20] = np.nan
    assert not fold_mask(m).any()


def test_neighbours_share_an_edge_both_ways() -> None:
    rows, cols = 4, 5
    tris = grid_triangles(rows, cols)
    nb = grid_neighbours(rows, cols)
    for t in range(tris.shape[0]):
        for k in range(3):
            s = nb[t, k]
            edge = {int(tris[t, (k + 1) % 3]), int(tris[t, (k + 2) % 3])}
            if s < 0:
                continue
            assert edge <= set(tris[s].tolist())  # they share that edge
            assert t in nb[s].tolist()  # and see each other across it
    # the border: every triangle on it lacks one neighbour there
    assert (nb < 0).sum() == 2 * (rows + cols)


def _seam_kinks(m: np.ndarray, grid_uv: np.ndarray) -> tuple[float, float]:
    """99th percentiles of how fast a pixel's step along x changes, at the grid's vertical
    lines and inside the cells (|log| of the ratio of consecutive steps)."""
    m = m.astype(np.float64)
    step = np.linalg.norm(np.diff(m, axis=1), axis=2)  # step from pixel x to x + 1
    with np.errstate(divide="ignore", invalid="ignore"):
        change = np.abs(np.log(step[:, 1:] / step[:, :-1]))  # at pixel x + 1
    at_line = np.zeros(change.shape[1], dtype=bool)
    at_line[grid_uv[0, 1:-1, 0].astype(int) - 1] = True
    ok = np.isfinite(change)
    seam, inner = change[ok & at_line[None, :]], change[ok & ~at_line[None, :]]
    assert seam.size > 1000 and inner.size > 100000
    return float(np.percentile(seam, 99)), float(np.percentile(inner, 99))


@pytest.mark.parametrize(
    ("name", "developable"),
    [("cylinder-convex", True), ("cone-wall", True), ("sphere-convex", False)],
)
def test_the_surface_map_is_continuous_across_the_seams(name: str, developable: bool) -> None:
    # next to an edge the two triangles' places are blended: no jump there, and the
    # map bends at a grid line far less than the perspective-correct interpolation does
    s = simulate_surface(name, step=2)
    settings = WarpSettings(mode="conformal", grid=Grid(20, 20), adaptive=False)
    warp = compute_warp(s, (640, 400), settings=settings)
    weights = PixelWeights.build(warp.grid_uv, warp.depth, warp.projector, s)
    assert weights.fallback is not None
    verts = warp.image_xy.astype(np.float32).reshape(-1, 2)
    surface_map = weights.map(warp.image_xy, warp.content_size, clip=False)
    plain = np.zeros_like(surface_map)
    for k in range(3):
        for c in range(2):
            plain[..., c] += weights.fallback[k] * verts[weights.corners[k], c]
    seam, inner = _seam_kinks(surface_map, warp.grid_uv)
    plain_seam, _ = _seam_kinks(plain, warp.grid_uv)
    assert seam < 0.5 * plain_seam, (seam, plain_seam)
    if developable:  # both sides are exact: at the seam it bends as inside the cells
        assert seam <= 1.5 * inner + 1e-4, (seam, inner)
    assert not fold_mask(surface_map).any()
