"""The crease of two fitted side patches against geometry known in closed form.

A plane wall meeting a circular cylinder along one of its rulings (the cylinder leaving
the wall at a known angle): the patches must meet on the ruling, with the wall's plane
and the cylinder's tangent plane there. A cylinder standing on a floor meets it along a
circle: not a straight crease, so no planes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.ruled_crease import crease_planes, side_patch

H = 0.05  # a triangle's size (m)
TOL = 1e-3 * H


def wall_and_cylinder(turn: float, radius: float) -> tuple[FloatArray, FloatArray]:
    """Points of the wall z = 0 (x <= 0) and of a cylinder (axis along y) leaving it at
    the ruling x = z = 0 at the angle ``turn`` and bending away, a few cells around."""
    ys = np.linspace(-1.5 * H, 1.5 * H, 7)
    xs = np.linspace(-2 * H, -0.1 * H, 6)
    wall = np.array([(x, y, 0.0) for x in xs for y in ys])
    centre = radius * np.array([-np.sin(turn), np.cos(turn)])
    arcs = np.linspace(0.1 * H, 2 * H, 6)
    cyl = []
    for s in arcs:
        a = turn + s / radius
        x, z = centre + radius * np.array([np.sin(a), -np.cos(a)])
        cyl += [(x, y, z) for y in ys]
    return wall, np.array(cyl)


@pytest.mark.parametrize("turn", [0.2, 0.5, 0.7])
@pytest.mark.parametrize("radius", [5 * H, 20 * H])
def test_the_patches_meet_on_the_ruling_with_its_tangent_planes(turn: float, radius: float) -> None:
    wall, cyl = wall_and_cylinder(turn, radius)
    centre = np.array([0.3 * H, 0.1 * H, 0.05 * H])
    a = side_patch(wall, centre, np.array([0.02, 0.0, 1.0]), TOL)
    b = side_patch(cyl, centre, np.array([-np.sin(turn + 0.1), 0.0, np.cos(turn + 0.1)]), TOL)
    assert a is not None and b is not None
    d = np.array([0.05, 1.0, 0.0]) / np.hypot(0.05, 1.0)  # the crease's direction, roughly
    met = crease_planes(a, b, centre, d, H, TOL)
    assert met is not None
    na, pa, nb, pb = met
    np.testing.assert_array_equal(pa, pb)  # both through the crease
    # on the ruling x = z = 0, to a small part of the sagitta of a cell (H^2 / 2 r)
    assert abs(pa[0]) < 0.02 * H * H / radius + 1e-9
    assert abs(pa[2]) < 0.02 * H * H / radius + 1e-9
    np.testing.assert_allclose(na, [0.0, 0.0, 1.0], atol=1e-9)
    # the cylinder's tangent plane there, to 5 % of a cell's bend (H / r): turning the
    # cylinder's side by that off its true angle moves its corners by its square only
    tangent = np.array([-np.sin(turn), 0.0, np.cos(turn)])
    assert np.arccos(min(1.0, float(nb @ tangent))) < 0.05 * H / radius


def test_a_cylinder_standing_on_a_floor_is_no_straight_crease() -> None:
    """The floor z = 0 and a cylinder of radius 10 cells with a vertical axis (z)
    standing on it: they meet along a circle, half a cell off its tangent line by
    H^2 / (8 r) = 1.25 % of a cell."""
    r = 10 * H
    ys = np.linspace(-1.5 * H, 1.5 * H, 7)
    floor = np.array([(x, y, 0.0) for x in np.linspace(-2 * H, -0.1 * H, 6) for y in ys])
    # the cylinder's wall (centre at x = r), rising along z from the floor at x = 0
    wall = np.array(
        [(r - np.sqrt(r * r - y * y), y, z) for z in np.linspace(0.1 * H, 2 * H, 6) for y in ys]
    )
    centre = np.array([0.1 * H, 0.0, 0.1 * H])
    a = side_patch(floor, centre, np.array([0.0, 0.0, 1.0]), TOL)
    b = side_patch(wall, centre, np.array([-1.0, 0.0, 0.0]), TOL)
    assert a is not None and b is not None
    assert crease_planes(a, b, centre, np.array([0.0, 1.0, 0.0]), H, TOL) is None


def test_a_surface_rough_all_over_is_given_up_on(monkeypatch: pytest.MonkeyPatch) -> None:
    # waves finer than the grid: hundreds of candidates per mesh, none a straight crease
    # between curved sides; they are tried until MISSES of them failed, not all (each
    # tries at most its two sides' patches)
    from adaproj_edge.geometry import creases, ruled_crease
    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.warp.adaptive import adaptive_mesh
    from adaproj_edge.warp.warpmap import Grid

    retries: list[int] = []
    patches: list[int] = []
    ruled, patch = ruled_crease.ruled_planes, ruled_crease.side_patch

    def counted_ruled(retry: np.ndarray, *args: Any) -> Any:
        retries.append(int(retry.size))
        return ruled(retry, *args)

    def counted_patch(*args: Any) -> Any:
        patches.append(1)
        return patch(*args)

    monkeypatch.setattr(creases, "ruled_planes", counted_ruled)
    monkeypatch.setattr(ruled_crease, "side_patch", counted_patch)
    adaptive_mesh(simulate_surface("waves-fine", step=2), Grid(20, 20))  # (as the planner)
    assert retries and max(retries) > 400, retries  # many candidates ...
    # ... of which few are tried: at most MISSES each mesh, two patches each
    assert 0 < len(patches) <= 2 * ruled_crease.MISSES * len(retries) < sum(retries) / 4


def test_a_sensed_surface_is_not_searched_for_ruled_creases(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a cone wall meeting a plane along a ruling (tools/stress_warp.py seed 3 case 51):
    # exact, its ruled crease is found; the same points as a depth sensor's surface
    # are known only to its millimetres, and no candidate is tried, by the warp's mesh
    # and by the display's unfolding alike
    from dataclasses import replace

    from adaproj_edge.geometry import creases
    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.render.seams import grid_unfolding
    from adaproj_edge.warp.mesh import MeshGeometry
    from adaproj_edge.warp.warpmap import Grid
    from tests.warp.random_surfaces import draw_case

    exact = simulate_surface(draw_case(3, 51).surface)
    grid = Grid(20, 20)
    assert MeshGeometry.build(exact, grid).ruled.any()
    tried: list[int] = []
    ruled = creases.ruled_planes

    def counted(retry: np.ndarray, *args: Any) -> Any:
        tried.append(int(retry.size))
        return ruled(retry, *args)

    monkeypatch.setattr(creases, "ruled_planes", counted)
    sensed = replace(exact, meta={**exact.meta, "source": "depth"})
    mesh = MeshGeometry.build(sensed, grid)
    depth = mesh.points[:, 2].reshape(mesh.grid_uv.shape[:2])
    shown = grid_unfolding(mesh.grid_uv, depth, exact.projector, sensed)
    assert not tried and not mesh.ruled.any() and not shown.ruled.any()
    assert mesh.folded.any()  # (its creases are unfolded with their corners' planes)


def test_on_sensed_depth_ruled_creases_are_looked_for_only_with_two_snapped_planes() -> None:
    # a crease with both sides known to a patch's tolerance needs two snapped planes;
    # with one (a bump on a snapped wall) or none, nowhere; on exact surfaces everywhere
    from dataclasses import replace

    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.geometry.creases import ruled_triangles
    from adaproj_edge.geometry.triangles import grid_triangles

    points = np.zeros((12, 3))
    tris = grid_triangles(2, 3)
    n = np.sqrt(1.25)
    planes = [[0.5 / n, 0.0, 1 / n, 1 / n], [-0.5 / n, 0.0, 1 / n, 1 / n]]
    exact = simulate_surface("corner", step=16)
    assert ruled_triangles(exact, points, tris) is None
    for listed, everywhere in ((planes, True), (planes[:1], False), ([], False)):
        sensed = replace(exact, meta={"source": "depth", "plane_equations": listed})
        got = ruled_triangles(sensed, points, tris)
        assert (got is None) if everywhere else (got is not None and not got.any())
