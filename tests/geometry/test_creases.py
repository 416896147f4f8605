"""The crease unfolding decides every triangle at once as the per-triangle rules do.

The reference (``crease_reference``) reads the rules triangle by triangle with its own
loops; the surfaces are the analytic ones with a crease (a wall corner, a half cylinder
on a floor, a cone meeting a wall) and smooth ones, exact and with depth noise as a
scanner gives it (none, 0.03 % and 0.3 % of the depth), at two grid sizes.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.creases import (
    Unfolding,
    _crease_groups,
    _pair_plane,
    crease_probes,
    unfold_creases,
)
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import grid_triangles
from adaproj_edge.warp.warpmap import Grid
from tests.geometry.crease_reference import crease_groups, side_plane, unfold_reference
from tests.warp.random_surfaces import Turned

Reference = dict[int, tuple[FloatArray, FloatArray, FloatArray, FloatArray, float, list[int]]]

SURFACES = ("corner", "cylinder-floor", "cone-wall", "sphere-concave", "bumps")


def grid_mesh(
    name: str, cells: int, noise: float, seed: int = 0
) -> tuple[Surface, FloatArray, IntArray, FloatArray, FloatArray]:
    """A ``cells`` x ``cells`` grid on surface ``name``: the surface, the triangles'
    pixel corners, their vertex indices, the vertices' and the probes' surface points
    (depth scaled by 1 + ``noise`` x a standard normal)."""
    surface = simulate_surface(name, step=4)
    p = surface.projector
    xs = np.linspace(0, p.width - 1, cells + 1)
    ys = np.linspace(0, p.height - 1, cells + 1)
    uv = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    tris = grid_triangles(cells, cells)
    tri_uv = uv[tris]
    rng = np.random.default_rng(seed)

    def at(q: FloatArray) -> FloatArray:
        pts = surface.points_at(q).astype(np.float64)
        return pts * (1 + noise * rng.standard_normal(pts.shape[:-1]))[..., None]

    return surface, tri_uv, tris, at(uv), at(crease_probes(tri_uv))


def unfold_both(
    surface: Surface, uv: FloatArray, tris: IntArray
) -> tuple[Unfolding, Reference, FloatArray]:
    """The product's unfolding of ``surface`` on the grid of vertices ``uv`` (n, 2) and
    triangles ``tris``, the reference's, and the vertices' surface points."""
    tri_uv = uv[tris]
    points = surface.points_at(uv).astype(np.float64)
    probes = surface.points_at(crease_probes(tri_uv)).astype(np.float64)
    got = unfold_creases(surface, tri_uv, tris, points, probes)
    return got, unfold_reference(tris, points, probes, tri_uv), points


def assert_same_planes(got: Unfolding, want: Reference, atol: float) -> None:
    """The same triangles unfolded, with the same planes and softness."""
    assert set(np.flatnonzero(got.folded)) == set(want)
    for t, (na, pa, nb, pb, softness, _) in want.items():
        np.testing.assert_allclose(got.normal_a[t], na, atol=atol)
        np.testing.assert_allclose(got.point_a[t], pa, atol=atol)
        np.testing.assert_allclose(got.normal_b[t], nb, atol=atol)
        np.testing.assert_allclose(got.point_b[t], pb, atol=atol)
        assert got.softness[t] == pytest.approx(softness, abs=1e-12)


@pytest.mark.parametrize("noise", [0.0, 0.0003, 0.003])
@pytest.mark.parametrize("cells", [20, 40])
@pytest.mark.parametrize("name", SURFACES)
def test_all_at_once_agrees_with_triangle_by_triangle(name: str, cells: int, noise: float) -> None:
    surface, tri_uv, tris, points, probes = grid_mesh(name, cells, noise)
    got = unfold_creases(surface, tri_uv, tris, points, probes)
    want = unfold_reference(tris, points, probes, tri_uv)
    assert_same_planes(got, want, atol=1e-12)
    for t, (*_, group_b) in want.items():
        side_a = [k for k in range(3) if k not in group_b]
        np.testing.assert_array_equal(got.points[t, side_a], points[tris[t, side_a]])
        moved = got.origin[t] + (points[tris[t, group_b]] - got.origin[t]) @ got.rotation[t].T
        np.testing.assert_allclose(got.points[t, group_b], moved, atol=1e-12)
    unfolded = ~got.folded
    np.testing.assert_array_equal(got.points[unfolded], points[tris[unfolded]])


def test_the_creased_surfaces_are_unfolded_somewhere() -> None:
    """The comparison above is not vacuous: each creased surface has unfolded triangles,
    and so do the corner and the half cylinder with a little depth noise (0.03 % of the
    depth; at 0.3 % many triangles are rough and none is unfolded: that case checks the
    rejections)."""
    for name, noise in (
        ("corner", 0.0),
        ("cylinder-floor", 0.0),
        ("cone-wall", 0.0),
        ("corner", 0.0003),
        ("cylinder-floor", 0.0003),
    ):
        surface, tri_uv, tris, points, probes = grid_mesh(name, 20, noise)
        got = unfold_creases(surface, tri_uv, tris, points, probes)
        assert got.folded.sum() >= 3, (name, noise)


def unit_normals(seed: int, count: int, spread: float) -> np.ndarray:
    """``count`` triples of unit normals around the viewing axis, tilted by up to
    ``spread`` radians: one plane, two, or three different planes."""
    rng = np.random.default_rng(seed)
    tilt = spread * rng.random((count, 3, 1)) * rng.choice([0.0, 0.2, 1.0], (count, 3, 1))
    turn = 2 * np.pi * rng.random((count, 3, 1))
    n = np.concatenate(
        [np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), -np.cos(tilt)], axis=2
    )
    return n


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31), st.floats(0.0, 1.6))
def test_crease_sides_agree_with_the_rules_triangle_by_triangle(seed: int, spread: float) -> None:
    """Which corners form each side, for triangles of one, two and three planes."""
    normals = unit_normals(seed, 64, spread)
    lone, pair_a = _crease_groups(normals)
    for c in range(normals.shape[0]):
        want = crease_groups(normals[c])
        if want is None:
            assert lone[c] == -1
            continue
        group_a, group_b = want
        single = group_b if len(group_b) == 1 else group_a
        assert lone[c] == single[0]
        assert bool(pair_a[c]) == (len(group_a) == 2)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31), st.floats(0.0, 1.6))
def test_a_two_corner_side_gets_the_plane_of_the_rules(seed: int, spread: float) -> None:
    normals = unit_normals(seed, 64, spread)
    points = np.random.default_rng(seed + 1).normal(size=(64, 3, 3))
    n, p = _pair_plane(normals[:, :2], points[:, :2], normals[:, 2])
    for c in range(normals.shape[0]):
        want_n, want_p = side_plane(normals[c, :2], points[c, :2], normals[c, 2])
        np.testing.assert_allclose(n[c], want_n, atol=1e-12)
        np.testing.assert_allclose(p[c], want_p, atol=1e-12)


def test_a_straight_crease_with_a_curved_side_agrees_triangle_by_triangle() -> None:
    """A wall meeting a sharp cone, rolled 18 deg (seed 1 case 101 of
    ``tools/stress_warp.py``), on its 15 x 18 grid: most triangles the crease clips are
    explained only by the sides' patches (the ruled rule: 39 unfolded, 25 without it),
    and both readings agree."""
    from tests.warp.random_surfaces import draw_case

    case = draw_case(1, 101)
    surface = simulate_surface(case.surface)
    uv = case.grid.vertices(surface.projector).reshape(-1, 2)
    got, want, _ = unfold_both(surface, uv, grid_triangles(case.grid.rows, case.grid.cols))
    assert_same_planes(got, want, atol=1e-9)
    assert len(want) >= 35  # 25 before the ruled rule, of the 42 the crease crosses


def test_a_crease_meeting_the_mesh_s_outline_agrees_triangle_by_triangle() -> None:
    """A wall meeting a narrow far cone (seed 3 case 26 of ``tools/stress_warp.py``), on
    its adaptive grid: where the crease meets the frame's bottom edge a cone vertex has
    only rough triangles (it borrows a neighbour's plane), and crease triangles whose
    corners' smooth triangles are too few are fitted from every smooth one within
    reach; both readings agree, and every triangle the crease crosses but three is
    unfolded (six missed before: then two near the top edge, where the crease clips a
    sliver of 0.8 % of their size, and one whose cone patch misses a probe by 1.8x the
    fit; on the grid split by the normal's turn, 50x28 since, the two triangles of one
    cell at rows 571-600 px)."""
    from tests.warp.random_surfaces import _warp, draw_case

    case = draw_case(3, 26)
    _, warp, _ = _warp(case, "content", "ours", case.mask)
    rows, cols = warp.grid_uv.shape[0] - 1, warp.grid_uv.shape[1] - 1
    surface = simulate_surface(case.surface)
    uv = warp.grid_uv.reshape(-1, 2).astype(np.float64)
    tris = grid_triangles(rows, cols)
    got, want, points = unfold_both(surface, uv, tris)
    assert_same_planes(got, want, atol=1e-9)
    side = case.surface.patch(np.nan_to_num(points))[tris]
    seen = np.isfinite(points).all(axis=1)[tris].all(axis=1)
    crossed = np.flatnonzero(seen & (side.min(axis=1) != side.max(axis=1)))
    missed = [int(t) for t in crossed if t not in want]
    assert len(missed) <= 3, missed


def wall_planes(analytic: Turned) -> list[tuple[FloatArray, FloatArray]]:
    """The two walls of a :class:`~adaproj_edge.geometry.analytic.Corner` turned about the
    projector: (unit normal, a point) each, written out from its definition (walls
    through the crease at ``half_angle`` to the axis)."""
    inner, rot = analytic.inner, np.asarray(analytic.rot)
    a = inner.half_angle
    out = []
    for side in (-1.0, 1.0):
        tangent = np.array([side * np.sin(a), 0.0, -np.cos(a) if inner.concave else np.cos(a)])
        n = np.cross(tangent, [0.0, 1.0, 0.0])
        out.append((rot @ (n / np.linalg.norm(n)), rot @ np.array([inner.x0, 0.0, inner.z0])))
    return out


@pytest.mark.parametrize(
    ("off", "yaw"),
    [(-0.5, 33.0), (-1.0, 33.0), (0.5, -33.0)],
    ids=["half-px", "one-px", "mirrored"],
)
def test_a_wall_seen_grazing_within_one_cell_is_unfolded_onto_its_plane(
    off: float, yaw: float
) -> None:
    """A convex 74 deg corner, one wall 4 deg from grazing and seen only inside the
    column of cells the crease runs through (default 20x20 grid, crease ``off`` px from
    the middle line). Its triangles are chords across the crease, huge on the surface:
    the other wall's sliver leaves some of them within ``SLIGHT`` of their plane, their
    planes outweighed the other wall's at the crease's vertices, and no triangle was
    unfolded (the display blended the grazing wall with the other wall's triangles:
    mean angle 0.04 at half a pixel, 2.4 at one). Every triangle the crease crosses is
    unfolded now (as the per-triangle reading of the rules unfolds it), and its unfolded
    corners lie on one wall's plane (computed here from the corner's definition), as the
    development puts them."""
    from tests.render.test_crease_display import corner_on_line

    analytic = corner_on_line(37.0, False, off, yaw, 0.0, False)
    surface = simulate_surface(analytic)
    uv = Grid().vertices(surface.projector).reshape(-1, 2)
    tris = grid_triangles(20, 20)
    got, want, points = unfold_both(surface, uv, tris)
    assert_same_planes(got, want, atol=1e-9)
    seen = np.isfinite(points).all(axis=1)[tris].all(axis=1)
    side = analytic.patch(np.nan_to_num(points))[tris]
    crossed = np.flatnonzero(seen & (side.min(axis=1) != side.max(axis=1)))
    assert crossed.size >= 20
    assert got.folded[crossed].all(), crossed[~got.folded[crossed]]
    walls = wall_planes(analytic)
    for t in crossed:
        n, p = max(walls, key=lambda w: abs(float(w[0] @ got.normal_a[t])))
        # float32 surface points 2-6 m away: ~1e-6 m each; the sliver's corners, a
        # millimetre from the crease, turned about it (a plane fitted over >= 2 cm
        # is within ~1e-4 rad): the corners lie on the wall within a few micrometres
        np.testing.assert_allclose((got.points[t] - p) @ n, 0.0, atol=1e-5)
