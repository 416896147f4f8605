"""The maximal inscribed rectangle."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.rectangle import (
    NEAR,
    Segments,
    boundary_edges,
    inscribed_rectangle,
    side_directions,
)
from adaproj_edge.geometry.triangles import grid_triangles


def grid_mesh(cols: int, rows: int, w: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = np.meshgrid(np.linspace(0, w, cols + 1), np.linspace(0, h, rows + 1))
    return np.stack([xs.ravel(), ys.ravel()], axis=1), grid_triangles(rows, cols)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_linf_clearance_is_the_sampled_minimum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    c, p0, p1 = rng.normal(size=(4, 2)), rng.normal(size=(6, 2)), rng.normal(size=(6, 2))
    p1[0] = p0[0]  # a point
    p1[1] = p0[1] + rng.normal() * np.array([1.0, 1.0])  # along a diagonal: |dx| = |dy|
    p1[2] = p0[2] + rng.normal() * np.array([1.0, -1.0])
    t = np.linspace(0, 1, 4001)[None, None, :, None]
    pts = p0[None, :, None, :] + t * (p1 - p0)[None, :, None, :]
    brute = np.abs(pts - c[:, None, None, :]).max(-1).min(-1).min(-1)
    segments = Segments(p0, p1)
    np.testing.assert_allclose(segments.clearance(c), brute, atol=2e-3)
    np.testing.assert_allclose(segments.distances(c).min(axis=1), brute, atol=2e-3)


def test_rectangle_fills_a_rectangle_of_its_aspect() -> None:
    v, tris = grid_mesh(8, 5, 16.0, 10.0)
    r = inscribed_rectangle(v, tris, 1.6)
    assert r.width == pytest.approx(16.0, rel=1e-3) and r.height == pytest.approx(10.0, rel=1e-3)


def test_rectangle_avoids_holes_and_stays_inside() -> None:
    v, tris = grid_mesh(10, 10, 10.0, 10.0)
    # punch a hole: drop the triangles of cell (row 5, col 2)
    keep = np.ones(len(tris), dtype=bool)
    keep[2 * (5 * 10 + 2) : 2 * (5 * 10 + 2) + 2] = False
    r = inscribed_rectangle(v, tris[keep], 1.0, near=0.0)  # the largest
    # the best square lies right of the hole: x in [3, 10], side 7
    assert r.width == pytest.approx(7.0, rel=2e-3)
    # asked for: the square nearest the region's centre within NEAR of the largest
    centred = inscribed_rectangle(v, tris[keep], 1.0, near=NEAR)
    assert 7.0 * (1 - NEAR) - 0.01 <= centred.width <= 7.0 + 1e-9  # the search stops at 4e-4
    assert r.x0 >= 3.0 - 1e-6
    assert r.x0 + r.width <= 10.0 + 1e-6 and r.y0 >= -1e-6 and r.y0 + r.height <= 10 + 1e-6


def test_boundary_edges_of_a_grid_are_its_outline() -> None:
    _, tris = grid_mesh(4, 3, 4.0, 3.0)
    assert len(boundary_edges(tris)) == 2 * (4 + 3)


def test_degenerate_region_is_an_error() -> None:
    v = np.zeros((3, 2))
    with pytest.raises(WarpError):
        inscribed_rectangle(v, np.array([[0, 1, 2]]), 1.0)


def test_side_directions_of_a_rotated_rectangle() -> None:
    a = np.radians(25.0)
    d = np.array([[np.cos(a), np.sin(a)]] * 5 + [[-np.sin(a), np.cos(a)]] * 3) * 2.0
    got = np.degrees(np.mod(np.arctan2(*side_directions(d)[:, ::-1].T), np.pi))
    assert sorted(np.round(got, 6)) == [25.0, 115.0]


def _rotated_region(angle_deg: float, aspect: float, jitter: float, seed: int) -> np.ndarray:
    v, _ = grid_mesh(16, 10, aspect, 1.0)
    v = v - v.mean(axis=0)
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    rng = np.random.default_rng(seed)
    out: np.ndarray = v @ R.T + rng.normal(scale=jitter, size=v.shape)
    return out


def test_content_turned_upright_in_a_rolled_frame_is_placed_stably() -> None:
    # the frame's footprint turned by 20 degrees (a rolled projector), slightly
    # distorted differently each time (noise, tremor): the content's centre stays put
    _, tris = grid_mesh(16, 10, 1.6, 1.0)
    centres, widths = [], []
    for seed in range(6):
        v = _rotated_region(20.0, 1.6, 0.002, seed)
        r = inscribed_rectangle(v, tris, 1.6, near=NEAR)
        centres.append([r.x0 + r.width / 2, r.y0 + r.height / 2])
        widths.append(r.width)
        # never much smaller than the largest the search finds (which, along the
        # ridge, it may even beat)
        best = inscribed_rectangle(v, tris, 1.6, near=0.0)
        assert r.width >= best.width * (1 - NEAR) - 1e-9
    assert np.ptp(np.array(centres), axis=0).max() < 0.02  # of a region 1.6 wide
    assert np.ptp(widths) < 0.01


def test_a_rectangle_that_can_slide_is_centred() -> None:
    # a square in a 16 x 10 region: the largest (side 10) slides from x 0 to 6
    v, tris = grid_mesh(8, 5, 16.0, 10.0)
    r = inscribed_rectangle(v, tris, 1.0)
    assert r.width == pytest.approx(10.0, rel=1e-3)
    assert r.x0 + r.width / 2 == pytest.approx(8.0, abs=0.05)
    assert r.y0 == pytest.approx(0.0, abs=0.01)
