"""The maximal inscribed rectangle."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry import rectangle
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


def _plain_climb(
    c: np.ndarray, r: float, step: float, tol: float, segments: Segments, pattern: np.ndarray
) -> tuple[np.ndarray, float]:
    """The climb's pattern search as documented, every trial over every segment."""
    while step > tol:
        trial = (c + step * pattern).reshape(-1, 2)
        rt = segments.clearance(trial)
        # only trials within the clearance (L-inf) of the centre: never across the outline
        rt[step * np.abs(pattern).max(axis=-1).ravel() >= r] = -np.inf
        k = int(np.argmax(rt))
        if rt[k] > r:
            c, r = trial[k], float(rt[k])
            scale = k // pattern.shape[1]
            step *= 2.0 if scale == 0 else 0.5**scale
        else:
            step /= 16.0
    return c, r


def assert_rounded_alike(
    got: tuple[np.ndarray, float], want: tuple[np.ndarray, float], extent: float
) -> None:
    """A search's centre and clearance ``got`` equal ``want`` up to a few roundings of
    coordinates of size ``extent`` (the search moves by at least 1e-5 of it)."""
    atol = 64 * np.finfo(float).eps * extent
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=atol)
    assert abs(got[1] - want[1]) <= atol


def _jittered_region(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A jittered, sheared 12 x 9 grid with a few cells missing (holes, notches)."""
    rng = np.random.default_rng(seed)
    v, tris = grid_mesh(12, 9, 1.0 + rng.random(), 1.0)
    v = v @ np.array([[1.0, 0.0], [rng.normal(scale=0.3), 1.0]]) + rng.normal(
        scale=0.01, size=v.shape
    )
    cells = rng.choice(len(tris) // 2, size=rng.integers(0, 6), replace=False)
    keep = np.ones(len(tris), dtype=bool)
    keep[2 * cells] = keep[2 * cells + 1] = False
    return v, tris[keep]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), warm=st.booleans())
# (a region whose climb once stepped across its outline, where the clearance grows
# without bound: the step doubled until it overflowed)
@example(seed=54381, warm=False)
def test_climb_over_nearby_segments_takes_the_plain_path(seed: int, warm: bool) -> None:
    # the climb evaluates its trials over the segments that can be nearest: the very
    # values, so the very path, of the search over all of them, from any start
    v, tris = _jittered_region(seed)
    edges = boundary_edges(tris)
    segments = Segments(v[edges[:, 0]], v[edges[:, 1]])
    # from a triangle's centre well inside (from near the outline, a step may jump out
    # of the region, where the clearance grows without bound)
    centres = v[tris].mean(axis=1)
    clearance = segments.clearance(centres)
    deep = np.flatnonzero(clearance >= 0.5 * clearance.max())
    c = centres[np.random.default_rng(seed).choice(deep)]
    extent = float(np.max(np.ptp(v, axis=0)))
    step = (0.002 if warm else 0.01) * extent
    pattern = (
        rectangle._SCALES[:, None, None]
        * np.concatenate([rectangle._DIRECTIONS, side_directions(v[edges[:, 1]] - v[edges[:, 0]])])[
            None
        ]
    )
    r = float(segments.clearance(c))
    tol = rectangle.TOLERANCE * extent
    got = rectangle._climb(c, r, step, tol, segments, pattern)
    want = _plain_climb(c, r, step, tol, segments, pattern)
    # the same path: its trials' clearances (a matrix product over fewer segments, whose
    # last bit may fall otherwise with another BLAS kernel) are rounded alike to an ulp
    # of the region's extent, far apart from each other on these jittered regions; a
    # nearest segment left out, or another path, is off by at least the search's steps
    assert_rounded_alike(got, want, extent)
    assert got[1] >= r
    assert rectangle._Triangles(np.ascontiguousarray(v.T), tris).inside(got[0])


def test_region_inside_and_centroid() -> None:
    # a 10 x 10 square less the unit cell at x in [2, 3], y in [5, 6]
    v, tris = grid_mesh(10, 10, 10.0, 10.0)
    keep = np.ones(len(tris), dtype=bool)
    keep[2 * (5 * 10 + 2) : 2 * (5 * 10 + 2) + 2] = False
    region = rectangle._Triangles(np.ascontiguousarray(v.T), tris[keep])
    want = (np.array([5.0, 5.0]) * 100.0 - np.array([2.5, 5.5])) / 99.0  # area moments
    np.testing.assert_allclose(region.centroid(), want, rtol=1e-12)
    assert region.inside(np.array([2.0 + 1e-9, 4.0])) and region.inside(np.array([9.9, 0.1]))
    assert not region.inside(np.array([2.5, 5.5])) and not region.inside(np.array([10.1, 5.0]))
    assert region.inside(np.array([3.0, 5.5]))  # on the hole's edge: in a triangle


def _plain_side_directions(d: np.ndarray, bins: int = 180) -> np.ndarray:
    """The two dominant directions as first written: the whole histogram's doubled
    angles, each peak's bins picked by their circular distance."""
    dx, dy = d[:, 0], d[:, 1]
    length = np.sqrt(dx * dx + dy * dy)
    angle = np.mod(np.arctan2(dy, dx), np.pi)
    k = np.minimum((angle / np.pi * bins).astype(np.intp), bins - 1)
    hist = np.bincount(k, weights=length, minlength=bins)
    ring = np.concatenate([hist[-1:], hist, hist[:1]])
    smooth = hist + ring[:-2] + ring[2:]
    first = int(np.argmax(smooth))
    half, apart = bins // 2, bins // 9
    smooth[np.arange(first - apart + 1, first + apart) % bins] = -1.0
    second = int(np.argmax(smooth))
    z2 = length * np.exp(2j * angle)
    out = np.empty((2, 2))
    for i, b in enumerate((first, second)):
        near = np.abs((k - b + half) % bins - half) <= 1
        z = complex(np.sum(z2[near]))
        a = 0.5 * np.angle(z) if abs(z) > 0 else (b + 0.5) * np.pi / bins
        out[i] = np.cos(a), np.sin(a)
    return out


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 120), rounded=st.booleans())
def test_side_directions_are_the_plain_ones(seed: int, n: int, rounded: bool) -> None:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 2))
    if rounded:  # directions on the bins' edges, repeated, axis-aligned
        d = np.round(d, 1)
        d[: n // 3, 1] = 0.0
    # the same bins (integer arithmetic), then unit vectors from the phase of a sum of at
    # most n terms within 6 degrees of each other (no cancellation), through exp, phase,
    # cos and sin that round differently by CPU and code path: a few ulps per term, below
    # 1e-13 for n <= 120; a wrong bin or a missing term moves them by far more than 1e-12
    np.testing.assert_allclose(side_directions(d), _plain_side_directions(d), rtol=0, atol=1e-12)


def _plain_centre(
    c: np.ndarray,
    r: float,
    least: float,
    goal: np.ndarray,
    tol: float,
    segments: Segments,
    pattern: np.ndarray,
) -> tuple[np.ndarray, float]:
    """The centring's pattern search as documented, its trials made afresh each step."""
    gap = float(np.linalg.norm(goal - c))
    step = gap
    while step > tol and gap > 0:
        toward = c + np.minimum(rectangle._SCALES * step / gap, 1.0)[:, None] * (goal - c)
        trial = np.concatenate([toward, (c + step * pattern).reshape(-1, 2)])
        rt = segments.clearance(trial)
        gaps = np.where(rt >= least, np.linalg.norm(trial - goal, axis=1), np.inf)
        k = int(np.argmin(gaps))
        if gaps[k] < gap:
            c, r, gap = trial[k], float(rt[k]), float(gaps[k])
        else:
            step *= 0.5
    return c, r


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_centring_takes_the_plain_path(seed: int) -> None:
    v, tris = _jittered_region(seed)
    edges = boundary_edges(tris)
    segments = Segments(v[edges[:, 0]], v[edges[:, 1]])
    region = rectangle._Triangles(np.ascontiguousarray(v.T), tris)
    extent = float(np.max(np.ptp(v, axis=0)))
    tol = rectangle.TOLERANCE * extent
    pattern = (
        rectangle._SCALES[:, None, None]
        * np.concatenate([rectangle._DIRECTIONS, side_directions(v[edges[:, 1]] - v[edges[:, 0]])])[
            None
        ]
    )
    centres = v[tris].mean(axis=1)
    c = centres[int(np.argmax(segments.clearance(centres)))]
    c, r = rectangle._climb(c, float(segments.clearance(c)), 0.01 * extent, tol, segments, pattern)
    goal = region.centroid()
    got = rectangle._centre(c, r, (1 - NEAR) * r, goal, tol, segments, pattern)
    want = _plain_centre(c, r, (1 - NEAR) * r, goal, tol, segments, pattern)
    assert_rounded_alike(got, want, extent)  # the same path, as the climb's
    assert got[1] >= (1 - NEAR) * r


def test_a_kept_rectangle_stays_while_it_is_nearly_the_largest() -> None:
    # a 4 x 1 strip: a unit square fits anywhere along x in [0.5, 3.5]
    v, tris = grid_mesh(16, 4, 4.0, 1.0)
    fresh = inscribed_rectangle(v, tris, 1.0)
    assert abs(fresh.x0 + 0.5 - 2.0) < 0.01  # centred
    kept = inscribed_rectangle(v, tris, 1.0, keep=np.array([1.0, 0.5]))
    # kept where it was shown (the clearance there is the largest's): not re-centred
    assert abs(kept.x0 + kept.width / 2 - 1.0) < 1e-9 and abs(kept.width - 1.0) < 0.01
    # too near the end (half the largest): moved to the nearest centre that is within
    # NEAR + KEEP_SLACK of it, at that size
    least = 1.0 - rectangle.NEAR - rectangle.KEEP_SLACK
    near_end = inscribed_rectangle(v, tris, 1.0, keep=np.array([0.25, 0.5]))
    cx = near_end.x0 + near_end.width / 2
    assert least - 0.01 <= near_end.width < 1.0 and abs(cx - least / 2) < 0.02, near_end
    # outside the region: a fresh search
    outside = inscribed_rectangle(v, tris, 1.0, keep=np.array([9.0, 0.5]))
    assert outside == fresh
