"""Detail finer than the grid: where the adaptive grid adds lines, and what it keeps."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import ConeWall, get_surface, simulate_surface
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.warp.adaptive import (
    BEND,
    MAX_FACTOR_ONE_WAY,
    MIN_SPACING,
    TURN_ONE_WAY,
    adaptive_mesh,
    bends,
    refine_grid,
)
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid
from tests.distortion import surface_points
from tests.warp.conftest import CONTENT, surface
from tests.warp.random_surfaces import Turned, _rot


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
    assert r.factor_x.max() <= MAX_FACTOR_ONE_WAY


def test_a_refined_developable_mesh_closes_up_around_its_vertices() -> None:
    """On the fine corrugations (54 px waves at 29 deg to the grid, cells of 12.8 px)
    the refined mesh's triangles took their shapes from their corners: the chords cut
    each wave's bend short by where the edge sits on it, the angles about an inner vertex
    summed to 2 pi +- 0.027 on average, and the conformal solve answered with a scale
    field (0.82 to 1.13) that held a picture 0.63x the paper warp's. A developable
    surface's triangles, taken from its development, close up exactly; with their sides
    measured on the development (adaproj_edge/geometry/developed.py) they are off by
    what that measure is (1e-3 of a side): 0.001 on average."""
    mesh, meta = adaptive_mesh(simulate_surface("waves-fine", step=2), Grid())
    assert meta  # refined
    shapes = mesh.shapes
    angles = np.empty((shapes.shape[0], 3))
    for k in range(3):
        a = shapes[:, (k + 1) % 3] - shapes[:, k]
        b = shapes[:, (k + 2) % 3] - shapes[:, k]
        cross = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        angles[:, k] = np.arctan2(cross, np.sum(a * b, axis=1))
    total = np.bincount(mesh.tris.ravel(), angles.ravel(), minlength=mesh.n)
    inner = np.ones(mesh.n, dtype=bool)
    inner[mesh.boundary.ravel()] = False
    assert np.abs(total - 2 * np.pi)[inner].mean() < 0.002


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


def test_oblique_rulings_are_split_until_every_triangle_turns_within_the_limit() -> None:
    """A wall meeting a cone along a ruling, rolled 30 deg: the crease and the cone's
    rulings run diagonally through the grid. Its normal turns along a column by
    ``kappa |sin a|`` though the column bends by ``kappa sin^2 a``, and along a cell's
    diagonal by the two turns' sum; before, the grid was split by the bends alone (and,
    the bends along x and y being alike, to the limit of a surface bending both ways),
    and the cone's triangles turned by up to 0.13 along their diagonals. Measured on
    the analytic surface: the angle between the normals at each refined edge's ends
    (rows, columns and the cells' diagonals), where the cone is seen within 60 deg of
    its normal and the grid was not split as far as it may be."""
    cone = Turned(
        ConeWall("cone-wall", x0=-0.2, z0=2.0, apex_y=-3.0, alpha=0.2, turn=0.4),
        _rot(np.array([0.0, 0.0, 1.0]), 30.0),
    )
    r = refine_grid(simulate_surface(cone), Grid())
    K = Projector.default().K
    uv = r.grid_uv

    def at(offset: list[float]) -> np.ndarray:
        return surface_points(cone, K, uv + np.array(offset))

    n = np.cross(at([0.5, 0.0]) - at([-0.5, 0.0]), at([0.0, 0.5]) - at([0.0, -0.5]))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    p = at([0.0, 0.0])
    # on the cone, 3 px clear of the crease, seen within 60 deg of its normal
    ok = np.isfinite(p).all(axis=-1) & np.isfinite(n).all(axis=-1)
    for d in ([0.0, 0.0], [-3.0, 0.0], [3.0, 0.0], [0.0, -3.0], [0.0, 3.0]):
        ok &= cone.patch(np.nan_to_num(at(d))) == 1
    ok &= np.abs(np.sum(n * p, axis=-1)) >= 0.5 * np.linalg.norm(p, axis=-1)
    # cells whose column and row were split fewer times than they may be
    free = (np.repeat(r.factor_y, r.factor_y)[:, None] < MAX_FACTOR_ONE_WAY) & (
        np.repeat(r.factor_x, r.factor_x)[None, :] < MAX_FACTOR_ONE_WAY
    )
    # each edge's ends, and the cells (of the edges' own, or the last row / column's)
    # it must be free in
    rows_free, cols_free = np.vstack([free, free[-1:]]), np.hstack([free, free[:, -1:]])
    edges = {
        "row": ((slice(None), slice(None, -1)), (slice(None), slice(1, None)), rows_free),
        "column": ((slice(None, -1), slice(None)), (slice(1, None), slice(None)), cols_free),
        "diagonal": ((slice(None, -1), slice(None, -1)), (slice(1, None), slice(1, None)), free),
    }
    worst = {}
    for name, (a, b, cells) in edges.items():
        keep = ok[a] & ok[b] & cells
        turn = np.arccos(np.clip(np.sum(n[a] * n[b], axis=-1), -1.0, 1.0))[keep]
        assert turn.size > 100, name
        worst[name] = float(turn.max())
    # the grid measures the surface every 8 px: a hair above the limit between samples
    assert max(worst.values()) <= 1.05 * TURN_ONE_WAY, worst
