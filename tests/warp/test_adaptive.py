"""Detail finer than the grid: where the adaptive grid adds lines, and what it keeps."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import get_surface
from adaproj_edge.warp.adaptive import BEND, MAX_FACTOR, MIN_SPACING, bends, refine_grid
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid
from tests.warp.conftest import CONTENT, surface


@pytest.mark.parametrize("name", ["plane", "tilted", "corner", "sphere-concave", "bowl"])
def test_a_surface_smooth_at_the_grid_scale_keeps_the_grid(name: str) -> None:
    # the corner's crease is a kink, not a bend: its unfolding is exact already
    r = refine_grid(surface(name), Grid())
    assert not r.refined and r.grid == Grid()


def test_the_bend_of_a_cylinder_is_its_cell_over_its_radius() -> None:
    # a vertical cylinder of radius r bends along x by kappa h = (cell width on it) / r
    s = surface("cylinder-concave")
    cyl = get_surface("cylinder-concave")
    grid_uv = Grid().vertices(s.projector)
    b = bends(s, grid_uv)
    bx, by = b.x, b.y
    # the middle cell: its width on the surface from the analytic points at its corners
    pts = s.points_at(grid_uv[10, 10:12]).astype(np.float64)
    width = float(np.linalg.norm(pts[1] - pts[0]))
    r = cyl.r  # type: ignore[attr-defined]
    assert bx[10, 10] == pytest.approx(width / r, rel=0.1)
    assert by.max() < 1e-3  # straight along its axis
    # its rulings run along the columns: the normal turns as the rows bend, and
    # the cylinder bends one way only
    assert b.turn_x[10, 10] == pytest.approx(bx[10, 10], rel=0.02)
    assert b.turn_y.max() < 1e-3 and b.two_way.max() == 0.0


def test_corrugations_split_the_columns_only() -> None:
    s = surface("waves")
    r = refine_grid(s, Grid())
    assert r.refined and np.all(r.factor_y == 1) and np.all(r.factor_x >= 4)
    base = Grid().vertices(s.projector)[0, :, 0]
    assert np.all(np.isin(base, r.xs))  # the base grid's lines stay
    assert np.all(r.xs[r.base_cols] == base)
    assert np.all(np.diff(r.xs) >= MIN_SPACING)
    assert r.factor_x.max() <= MAX_FACTOR


def test_relief_splits_only_the_columns_and_rows_it_crosses() -> None:
    r = refine_grid(surface("bumps"), Grid())
    assert r.refined
    assert (r.factor_x == 1).any() and (r.factor_y == 1).any()  # not everywhere


def test_a_curved_crease_splits_its_cells_both_ways() -> None:
    s = surface("cylinder-floor")
    mesh = MeshGeometry.build(s, Grid())
    cells = mesh.curved_cells
    assert cells.size >= 10  # the junction runs across the frame
    r = refine_grid(s, Grid(), cells)
    rows = np.unique(cells // 20)
    assert np.all(r.factor_y[rows] >= 4)
    assert np.all(r.factor_x[np.unique(cells % 20)] >= 4)


def test_the_budget_holds() -> None:
    r = refine_grid(surface("bumps"), Grid(), budget=1500)
    assert (r.grid.cols + 1) * (r.grid.rows + 1) <= 1500 and r.refined


def test_the_warp_of_a_refined_grid_keeps_the_base_vertices() -> None:
    s = surface("waves")
    w = compute_warp(s, CONTENT, settings=WarpSettings(mode="conformal"))
    r = refine_grid(s, Grid())
    assert w.grid_uv.shape == (r.grid.rows + 1, r.grid.cols + 1, 2)
    assert w.meta["mesh"] == str(r.grid) and w.meta["refined"]["columns"] == r.factor_x.tolist()
    off = compute_warp(s, CONTENT, settings=WarpSettings(mode="conformal", adaptive=False))
    assert off.grid_uv.shape == (21, 21, 2) and "mesh" not in off.meta
    assert BEND > 0
