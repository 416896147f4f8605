"""The warp planner: coarse-to-fine content-aware refinement (the device's method) and
the fast display maps, against analytic ground truth (tests/distortion.py) and exact
fields; and compute_warp as the planner's one-shot path."""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.analytic import DEVELOPABLE, NON_DEVELOPABLE, get_surface
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.render.frame import RemapMaps
from adaproj_edge.warp import guard as guard_module
from adaproj_edge.warp import planner as planner_module
from adaproj_edge.warp.coarse import (
    coarse_cells_of,
    coarse_indices,
    filled_by_shapes,
    upsample_field,
)
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.orientation import fold_count
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner, compute_warp
from adaproj_edge.warp.warpmap import Grid, Warp
from tests.distortion import Distortion, in_mask, measure, visible_fraction
from tests.shown_maps import shown_map
from tests.warp.conftest import CONTENT, subject_masks, surface
from tests.warp.random_surfaces import draw_case, simulate_surface


def test_coarse_indices_are_fine_vertices_with_both_ends() -> None:
    assert coarse_indices(20, 2).tolist() == list(range(0, 21, 2))
    assert coarse_indices(20, 1).tolist() == list(range(21))
    for cells in (3, 7, 15, 31):
        idx = coarse_indices(cells, 2)
        assert idx[0] == 0 and idx[-1] == cells
        assert np.all(np.diff(idx) >= 1) and idx.size - 1 <= cells // 2 + 1
    assert coarse_indices(2, 4).tolist() == [0, 1, 2]  # never fewer than 2 cells


def test_upsampling_reproduces_bilinear_fields_exactly() -> None:
    rows, cols = np.array([0, 3, 5, 9]), np.array([0, 2, 6, 7, 12])
    ii, jj = np.meshgrid(np.arange(10.0), np.arange(13.0), indexing="ij")
    field = np.stack([2 + 0.5 * ii - 1.5 * jj + 0.25 * ii * jj, -ii + 3 * jj], axis=-1)
    coarse = field[np.ix_(rows, cols)]
    assert np.allclose(upsample_field(coarse, rows, cols, (10, 13)), field, atol=1e-9)
    # an unknown coarse value takes its nearest known neighbour's: finite everywhere
    coarse[1, 2] = np.nan
    out = upsample_field(coarse, rows, cols, (10, 13))
    assert np.isfinite(out).all()
    assert np.allclose(out[rows[0], cols[0]], field[0, 0])


def test_coarse_cells_of_fine_triangles_are_their_cells_and_neighbours() -> None:
    rows, cols = np.array([0, 2, 5, 6, 9]), np.array([0, 3, 4, 8])  # fine: 9 x 8 cells
    fine_cols = 8
    rng = np.random.default_rng(4)
    fine = rng.choice(2 * 9 * fine_cols, size=3, replace=False)
    got = coarse_cells_of(fine, fine_cols, rows, cols)
    assert got.shape == (2 * 4 * 3,)
    # by hand: a coarse cell (i, j) spans fine rows rows[i]..rows[i + 1] - 1, likewise
    # columns; a coarse triangle is marked when its cell or one of its 8 neighbours
    # holds a marked fine triangle's cell
    holds = np.zeros((4, 3), dtype=bool)
    for t in fine:
        r, c = divmod(int(t) // 2, fine_cols)
        for i in range(4):
            for j in range(3):
                if rows[i] <= r < rows[i + 1] and cols[j] <= c < cols[j + 1]:
                    holds[i, j] = True
    for i in range(4):
        for j in range(3):
            want = holds[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2].any()
            assert got[2 * (3 * i + j)] == got[2 * (3 * i + j) + 1] == want, (i, j)
    assert not coarse_cells_of(np.zeros(0, dtype=np.intp), fine_cols, rows, cols).any()


@pytest.mark.parametrize(("seed", "index"), [(3, 51), (3, 159)])
def test_the_coarse_mesh_finds_the_ruled_creases_next_to_the_fine_meshs(
    seed: int, index: int
) -> None:
    # a cone wall meeting a plane along a ruling, diagonally through the grid: the
    # device's coarse mesh looks for a straight crease between curved sides only next
    # to those the fine mesh found, and finds there what it finds looking everywhere
    case = draw_case(seed, index)
    assert case.kind == "cone-wall"
    sim = simulate_surface(case.surface)
    planner = WarpPlanner(sim.projector, plan=PlanSettings(refine_factor=2))
    settings = WarpSettings(mode="content", threshold=0.5)
    cf = planner.content_free(sim, CONTENT, settings)
    planner.refine(sim, ContentMap(subject_masks()["one-left"], CONTENT, 0.5), settings, cf)
    ((grid_name, hinted),) = cf.refinement_meshes.items()
    assert grid_name == "10x10" and cf.mesh.ruled.any() and hinted.ruled.any()
    everywhere = MeshGeometry.build(sim, hinted.grid, None, hinted.grid_uv)
    np.testing.assert_array_equal(hinted.topology.rows, everywhere.topology.rows)
    np.testing.assert_array_equal(hinted.ruled, everywhere.ruled)
    np.testing.assert_array_equal(hinted.folded, everywhere.folded)
    np.testing.assert_allclose(hinted.shapes, everywhere.shapes, rtol=0, atol=1e-12)
    # and nowhere, where it is told so
    nowhere = np.zeros(2 * hinted.grid.rows * hinted.grid.cols, dtype=bool)
    blind = MeshGeometry.build(sim, hinted.grid, None, hinted.grid_uv, nowhere)
    assert not blind.ruled.any()


def test_vertices_missing_from_a_mesh_are_filled_where_its_triangles_shapes_put_them() -> None:
    # a developable surface: the conformal solve is exact up to the banded solver's
    # precision (its eq. 4 residual is ~1e-6 of the positions' extent here), so each
    # dropped vertex must come back where the solve put it to well within 1e-4 of that
    # extent - whether next to known vertices or several triangles away from them
    s = surface("cylinder-convex")
    cf = WarpPlanner(s.projector).content_free(s, CONTENT, WarpSettings())
    mesh, v = cf.mesh, cf.v_conformal
    extent = float(np.ptp(v, axis=0).max())
    grid = mesh.grid.cols + 1
    dropped = np.isin(mesh.verts, [10 * grid + 10, 10 * grid + 11, 11 * grid + 11, 0, 5])
    gone = v.copy()
    gone[dropped] = np.nan
    filled = filled_by_shapes(gone, mesh.tris, mesh.coords)
    assert filled is not None
    np.testing.assert_array_equal(filled[~dropped], v[~dropped])
    np.testing.assert_allclose(filled[dropped], v[dropped], rtol=0, atol=1e-4 * extent)
    # none known, or one no triangle reaches: no positions
    assert filled_by_shapes(np.full_like(v, np.nan), mesh.tris, mesh.coords) is None
    alone = np.zeros((3, 2))
    alone[2] = np.nan
    assert filled_by_shapes(alone, np.array([[0, 1, 0]]), np.zeros((1, 3, 2))) is None


def test_a_coarse_vertex_the_fine_mesh_misses_keeps_the_content_free_placement(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # sensed depth: holes around a fine vertex that the coarse grid keeps (its coarse
    # triangles bridge them). The first refinement started there from a fresh solve of
    # the coarse mesh placed afresh (on recorded real depth, hundreds of content pixels
    # away from where the content-free warp shows the content, and a third of the
    # refinement's time); it starts from the content-free warp's own placement
    s = surface("cylinder-convex")
    points = s.points.copy()
    for dr, dc in [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]:
        u, v = 64 * (10 + dc), 40 * (10 + dr)  # the 20x20 grid's vertices near its centre
        points[v - 3 : v + 4, u - 3 : u + 4] = np.nan
    holed = replace(s, points=points)
    planner = WarpPlanner(s.projector, plan=PlanSettings(refine_factor=2))
    settings = WarpSettings(mode="content", threshold=CONTENT_MAP_T)
    cf = planner.content_free(holed, CONTENT, settings)
    centre = 10 * (planner.grid.cols + 1) + 10
    assert centre not in cf.verts  # the fine mesh misses it
    placed_on: list[str] = []
    place = planner_module.place
    monkeypatch.setattr(
        planner_module,
        "place",
        lambda mesh, *a, **k: placed_on.append(str(mesh.grid)) or place(mesh, *a, **k),
    )
    cmap = ContentMap(subject_masks()["quarter"], CONTENT, CONTENT_MAP_T)
    warp = planner.refine(holed, cmap, settings, cf)
    (coarse,) = cf.refinement_meshes.values()
    assert 5 * (planner.coarse_grid.cols + 1) + 5 in coarse.verts  # the coarse mesh holds it
    assert str(planner.coarse_grid) not in placed_on  # no placement of its own
    assert warp.meta["chain"]["step"] == "content-aware"
    assert fold_count(warp) == 0


def test_fold_count_sees_a_flipped_vertex() -> None:
    p = Projector.default()
    grid_uv = Grid(4, 4).vertices(p)
    w = Warp(grid_uv, grid_uv.copy(), (p.width, p.height), p)
    assert fold_count(w) == 0
    flipped = grid_uv.copy()
    flipped[2, 2] = grid_uv[2, 2] + 2.2 * (grid_uv[3, 3] - grid_uv[2, 2])
    assert fold_count(Warp(grid_uv, flipped, (p.width, p.height), p)) > 0


def test_upsampled_maps_follow_a_projective_map_to_a_thirtysecond_of_a_pixel() -> None:
    # a projective map, sampled at the quarter-resolution pixel centres, upsampled into
    # fixed-point maps: back in float, it matches the map at full resolution
    W, H, f = 1280, 800, 4
    Hm = np.array([[0.9, 0.05, 20.0], [-0.03, 1.1, 5.0], [1e-5, 2e-5, 1.0]])

    def apply(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        q = Hm @ np.stack([x.ravel(), y.ravel(), np.ones(x.size)])
        return (q[:2] / q[2]).T.reshape(*x.shape, 2)

    ys, xs = np.mgrid[0 : H // f, 0 : W // f].astype(np.float64)
    small = apply((xs + 0.5) * f - 0.5, (ys + 0.5) * f - 0.5).astype(np.float32)
    maps = RemapMaps.upsampled(small, (W, H))
    back = cv2.convertMaps(maps.map1, maps.map2, cv2.CV_32FC2)[0]
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    want = apply(xx, yy)
    inner = (slice(f, H - f), slice(f, W - f))  # clamped at the outermost half pixel
    err = np.abs(back[inner] - want[inner]).max()
    assert err < 1 / 32 + 0.02, err  # fixed point + bilinear between 4-px samples


def test_no_surface_shows_black_in_the_upsampled_maps() -> None:
    small = np.full((200, 320, 2), 50.0, np.float32)
    small[:, 160:] = np.nan
    maps = RemapMaps.upsampled(small, (1280, 800))
    content = np.full((100, 100, 3), 255, np.uint8)
    frame = cv2.remap(content, maps.map1, maps.map2, cv2.INTER_LINEAR)
    assert frame[:, :600].min() == 255 and frame[:, 660:].max() == 0


CONTENT_MAP_T = 0.5


@cache
def _pipeline_map(name: str, mask: str, factor: int) -> tuple[Warp, NDArray[np.float32]]:
    s = surface(name)
    planner = WarpPlanner(s.projector, plan=PlanSettings(refine_factor=factor))
    settings = WarpSettings(mode="content", threshold=CONTENT_MAP_T)
    cmap = ContentMap(subject_masks()[mask], CONTENT, CONTENT_MAP_T)
    cf = planner.content_free(s, CONTENT, settings)
    warp = planner.refine(s, cmap, settings, cf)
    return warp, shown_map(warp, s)


def _measured(name: str, m: NDArray[np.float32]) -> Distortion:
    return measure(m, get_surface(name), surface(name).projector.K)


@cache
def _engine(name: str, mode: str, mask: str | None) -> Distortion:
    s = surface(name)
    cmap = None if mask is None else subject_masks()[mask]
    # on the device's grid (compute_warp would refine it where the surface bends)
    settings = WarpSettings(mode=mode, threshold=CONTENT_MAP_T, adaptive=False)
    warp = compute_warp(s, CONTENT, cmap, settings)  # type: ignore[arg-type]
    return _measured(name, shown_map(warp, s))


# the device's 10x10 refinement on the convex sphere with the subject left of the
# centred picture: alone it is worse in angle than the conformal warp, so the guard
# blends it (t = 0.75), and the blend's size spread is 0.63x the conformal warp's
SHORT_ON_THE_DEVICE = {("sphere-convex", "one-left")}


@pytest.mark.parametrize(
    ("name", "mask"),
    [
        pytest.param(
            n,
            m,
            marks=pytest.mark.xfail(
                (n, m) in SHORT_ON_THE_DEVICE, reason="size 0.63x after the guard", strict=True
            ),
        )
        for n in NON_DEVELOPABLE
        for m in ("one-left", "two-apart")
    ],
)
def test_coarse_refinement_keeps_the_subject_as_the_full_grid_does(name: str, mask: str) -> None:
    m = subject_masks()[mask]
    warp, map_xy = _pipeline_map(name, mask, 2)
    ours = _measured(name, map_xy)
    conf = _engine(name, "conformal", None)
    full = _engine(name, "content", mask)
    ours_in, conf_in, full_in = (d.select(in_mask(d, m)) for d in (ours, conf, full))
    # the issue-2 bar for the subject, and no more than 1.5x the full-grid refinement's
    assert ours_in.size_std <= 0.6 * conf_in.size_std, (ours_in.size_std, conf_in.size_std)
    assert ours_in.size_std <= 1.5 * full_in.size_std + 0.002, (ours_in.size_std, full_in.size_std)
    assert ours_in.angle_mean <= 1.1 * conf_in.angle_mean, (ours_in.angle_mean, conf_in.angle_mean)
    assert ours.folds == 0 and fold_count(warp) == 0
    assert visible_fraction(map_xy, CONTENT) >= 0.995
    assert warp.meta["refine_grid"] == "10x10"


@pytest.mark.parametrize("name", DEVELOPABLE)
def test_coarse_refinement_stays_exact_on_developable_surfaces(name: str) -> None:
    _, map_xy = _pipeline_map(name, "one-left", 2)
    d = _measured(name, map_xy)
    assert d.angle_mean <= 0.005 and d.size_std <= 0.005, (d.angle_mean, d.size_std)
    assert d.folds == 0 and visible_fraction(map_xy, CONTENT) >= 0.995


@pytest.mark.parametrize("name", ["sphere-convex", "bowl"])
def test_full_grid_planning_is_compute_warp(name: str) -> None:
    # one path: the planner's steps on the full grid give compute_warp's warp
    s = surface(name)
    settings = WarpSettings(mode="content", threshold=CONTENT_MAP_T)
    cmap = ContentMap(subject_masks()["one-left"], CONTENT, CONTENT_MAP_T)
    planner = WarpPlanner(s.projector)
    stepwise = planner.refine(s, cmap, settings, planner.content_free(s, CONTENT, settings))
    once = compute_warp(s, CONTENT, cmap, settings)
    assert once.meta["iterations"] == stepwise.meta["iterations"] > 0
    np.testing.assert_allclose(once.image_xy, stepwise.image_xy, rtol=0, atol=1e-6)


def test_warm_start_takes_at_most_the_warm_steps_from_the_last_solution(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    copies = []
    depth = planner_module._surface_depth
    monkeypatch.setattr(planner_module, "_surface_depth", lambda s: copies.append(1) or depth(s))
    s = surface("sphere-convex")
    settings = WarpSettings(mode="content", threshold=CONTENT_MAP_T)
    cmap = ContentMap(subject_masks()["one-left"], CONTENT, CONTENT_MAP_T)
    warm = PlanSettings(refine_factor=2, warm_start=True, warm_iterations=2)
    planner = WarpPlanner(s.projector, plan=warm)
    cf = planner.content_free(s, CONTENT, settings)
    first = planner.refine(s, cmap, settings, cf)
    again = planner.refine(s, cmap, settings, cf)
    assert first.meta["iterations"] > 2 >= again.meta["iterations"]
    # without the kept solution it starts cold again: the first refinement, exactly
    planner.forget()
    cold = planner.refine(s, cmap, settings, cf)
    np.testing.assert_allclose(cold.image_xy, first.image_xy, rtol=0, atol=1e-9)
    # one surface's depth is copied once, not twice a warp (a video frame's refinement
    # paid ~3.4 ms of 33 for the two copies at 1280x800)
    assert len(copies) == 1


def test_a_content_free_warp_placed_for_another_up_is_the_one_solved_for_it() -> None:
    s = surface("sphere-concave")
    planner = WarpPlanner(s.projector, plan=PlanSettings(refine_factor=2), cache=None)
    level = WarpSettings(mode="content")
    a = np.deg2rad(8.0)
    rolled = WarpSettings(mode="content", up=(np.sin(a), -np.cos(a), 0.0))
    first = planner.content_free(s, CONTENT, level)
    turned = planner.with_up(first, rolled.up)
    solved = planner.content_free(s, CONTENT, rolled)
    assert np.allclose(turned.warp.image_xy, solved.warp.image_xy, atol=1e-9, equal_nan=True)
    assert turned.placement.angle == pytest.approx(solved.placement.angle, abs=1e-12)
    assert abs(turned.placement.angle - first.placement.angle) == pytest.approx(a, abs=0.02)
    assert np.array_equal(turned.up, solved.up)
    assert turned.refinement_meshes is first.refinement_meshes  # the same surface


def test_what_a_refinement_measures_of_the_conformal_warp_is_made_ahead_for_its_up(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a settled device makes the conformal placement and the guard's measure of the
    # conformal warp in the frame it makes the content-free warp: its first refinement
    # makes neither again, and gives the same warp as one that made them itself
    s = surface("sphere-concave")
    level = WarpSettings(mode="content", threshold=CONTENT_MAP_T)
    a = np.deg2rad(8.0)
    rolled = replace(level, up=(np.sin(a), -np.cos(a), 0.0))
    cmap = ContentMap(subject_masks()["quarter"], CONTENT, CONTENT_MAP_T)
    planner = WarpPlanner(s.projector, plan=PlanSettings(refine_factor=2), cache=None)
    cf = planner.content_free(s, CONTENT, level)
    cf.prepare(cmap, level.up)
    # re-placed for another "up": nothing made for the first one is kept
    turned = planner.with_up(cf, rolled.up)
    turned.prepare(cmap, rolled.up)
    fresh = planner_module.place(turned.mesh, turned.v_conformal, CONTENT, rolled.up)
    assert turned.conformal_placement.angle == pytest.approx(fresh.angle, abs=1e-12)
    assert abs(turned.conformal_placement.angle - cf.conformal_placement.angle) > 0.1
    xy = turned.guard_memo(cmap, rolled.up)["conformal"][0]
    np.testing.assert_allclose(xy, fresh.apply(turned.v_conformal), rtol=0, atol=1e-9)
    placed: list[str] = []
    measured_xy: list[np.ndarray] = []
    place, measured = planner_module.place, guard_module._measured
    monkeypatch.setattr(
        planner_module, "place", lambda m, *a, **k: placed.append(str(m.grid)) or place(m, *a, **k)
    )
    monkeypatch.setattr(
        guard_module, "_measured", lambda m, xy, c: measured_xy.append(xy) or measured(m, xy, c)
    )
    ahead = planner.refine(s, cmap, rolled, turned)
    assert placed == [] and measured_xy  # the guard measured its candidates alone
    assert not any(np.array_equal(m, xy, equal_nan=True) for m in measured_xy)
    monkeypatch.undo()
    unprepared = planner.with_up(cf, rolled.up)  # (no warm start: the plan keeps none)
    np.testing.assert_array_equal(
        planner.refine(s, cmap, rolled, unprepared).image_xy, ahead.image_xy
    )
