"""The upright angle of a placement, against a triangle-by-triangle computation; a
placement carried over to scaled positions; the placement shown turned with the mesh."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.placement import TURN_KEPT, place, turned_with_mesh, upright_angle
from adaproj_edge.warp.solve import solve_conformal
from adaproj_edge.warp.warpmap import Grid


@pytest.fixture(scope="module")
def bowl() -> MeshGeometry:
    return MeshGeometry.build(simulate_surface("bowl", step=8), Grid(12, 9))


def _by_triangle(
    mesh: MeshGeometry, v: np.ndarray, up: np.ndarray, tris: np.ndarray | None = None
) -> float:
    """Down on each triangle's plane (of ``tris``, by default all) carried to content
    space by the triangle's own affine map (least squares over its corners), weighted
    by area times its length."""
    down = -up / np.linalg.norm(up)
    total = np.zeros(2)
    for tri in mesh.tris if tris is None else tris:
        p, q = mesh.p[tri], v[tri]
        e = np.stack([p[1] - p[0], p[2] - p[0]], axis=1)  # (3, 2)
        n = np.cross(e[:, 0], e[:, 1])
        area = 0.5 * np.linalg.norm(n)
        n /= np.linalg.norm(n)
        g = down - (n @ down) * n
        coef = np.linalg.lstsq(e, g, rcond=None)[0]
        d = np.stack([q[1] - q[0], q[2] - q[0]], axis=1) @ coef
        total += area * np.linalg.norm(g) * d / np.linalg.norm(d)
    return float(np.pi / 2 - np.arctan2(total[1], total[0]))


@settings(max_examples=15, deadline=None)
@given(turn=st.floats(-3.0, 3.0), shear=st.floats(-0.3, 0.3), tilt=st.floats(-0.6, 0.6))
def test_upright_angle_is_the_weighted_mean_down(
    bowl: MeshGeometry, turn: float, shear: float, tilt: float
) -> None:
    rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    v = bowl.p[:, :2] @ np.array([[1.0, shear], [0.0, 1.0]]) @ rot.T  # some flat map
    up = np.array([np.sin(tilt), -np.cos(tilt), 0.1])
    got, want = upright_angle(bowl, v, up), _by_triangle(bowl, v, up)
    assert np.cos(got - want) == pytest.approx(1.0, abs=1e-12)


def test_upright_angle_undoes_a_turn_of_a_flat_wall() -> None:
    mesh = MeshGeometry.build(simulate_surface("plane", step=8), Grid(8, 6))
    turn = 0.4
    rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    # the wall faces the projector: its x, y are those of the projector's frame
    angle = upright_angle(mesh, mesh.p[:, :2] @ rot.T, np.array([0.0, -1.0, 0.0]))
    assert angle == pytest.approx(-turn, abs=1e-9)


@pytest.mark.parametrize("k", [0.5, 1.7, 3.0])
def test_a_placement_for_scaled_positions_is_the_placement_they_get(
    bowl: MeshGeometry, k: float
) -> None:
    """``for_scaled(k)`` of the placement of ``v`` is the placement of ``k v``: the same
    content positions, and the rectangle's centre where placing ``k v`` puts it (the
    warm start of the content-aware alternation's first placement)."""
    v = solve_conformal(bowl)
    p = place(bowl, v, (640, 400))
    carried = p.for_scaled(k)
    fresh = place(bowl, k * v, (640, 400))
    np.testing.assert_allclose(carried.apply(k * v), p.apply(v), atol=1e-9)
    np.testing.assert_allclose(carried.apply(k * v), fresh.apply(k * v), atol=1e-6)
    assert carried.centre is not None and fresh.centre is not None
    np.testing.assert_allclose(carried.centre, fresh.centre, rtol=1e-9)


def test_the_content_is_upright_where_it_lands_not_on_average() -> None:
    """A flattening that turns "down" from place to place (a messy piece of real depth
    does): the left of a wall laid out three times larger and turned 25 deg, the right
    as it is. The content lands on the left (the largest rectangle); its up is the up
    of the triangles it covers (checked triangle by triangle on them), not the whole
    mesh's mean, which the right part pulls about 10 deg away."""
    mesh = MeshGeometry.build(simulate_surface("plane", step=8), Grid(16, 8))
    x, y = mesh.p[:, 0], mesh.p[:, 1]
    u = (x - x.min()) / (x.max() - x.min())
    left = 1.0 / (1.0 + np.exp((u - 0.45) / 0.03))  # 1 on the left, 0 on the right
    turn = 0.44 * left  # 25 deg on the left
    k = 1.0 + 2.0 * left
    v = np.stack(
        [k * (np.cos(turn) * x - np.sin(turn) * y), k * (np.sin(turn) * x + np.cos(turn) * y)],
        axis=1,
    )
    size = (400, 300)
    up = np.array([0.0, -1.0, 0.0])
    placed = place(mesh, v, size, up)
    content = placed.apply(v)
    centres = content[mesh.tris].mean(axis=1)
    under = (
        (centres[:, 0] >= -0.5)
        & (centres[:, 0] <= size[0] - 0.5)
        & (centres[:, 1] >= -0.5)
        & (centres[:, 1] <= size[1] - 0.5)
    )
    assert under.sum() > 20 and np.all(u[mesh.tris[under]].mean(axis=1) < 0.5)  # the left
    # the triangles it covers, one by one: their mean down is the content's +y (within
    # 1 deg: the rectangle moves a little once turned, and with it the triangles under it)
    want = _by_triangle(mesh, v, up, mesh.tris[under])
    assert np.cos(placed.angle - want) > np.cos(np.radians(1.0))
    whole = upright_angle(mesh, v, up)
    assert np.cos(placed.angle - whole) < np.cos(np.radians(5.0))


def test_the_content_shown_turns_with_the_mesh_under_it() -> None:
    """The content-aware alternation keeps its start's rotation while its solves turn the
    mesh (a degree on a rolled device before a turned wall): the placement shown turns
    with the mesh, less the dead band. A flat wall facing the projector, its flattening
    turned as a whole: down on every triangle turns by exactly that much (checked
    triangle by triangle, independently of ``upright_angle``), so the content shown
    stands off upright by the dead band alone (to 1e-9 rad: only the rectangle moves);
    within the band the placement is kept as it is."""
    mesh = MeshGeometry.build(simulate_surface("plane", step=8), Grid(8, 6))
    origin = mesh.p[:, :2]  # the wall faces the projector: its x, y are the frame's
    size, up = (400, 300), np.array([0.0, -1.0, 0.0])
    start = place(mesh, origin, size, up)
    for turn_deg in (1.0, -2.5):
        turn = np.radians(turn_deg)
        rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
        v = origin @ rot.T
        shown = turned_with_mesh(mesh, origin, v, start, size, up)
        want = _by_triangle(mesh, v, up)
        off = float(np.angle(np.exp(1j * (shown.angle - want))))
        assert abs(off) == pytest.approx(TURN_KEPT, abs=1e-9)
        content = shown.apply(v)  # placed again: the mesh spans the content's width
        assert content[:, 0].min() <= -0.5 and content[:, 0].max() >= size[0] - 0.5
    small = np.radians(0.05)
    v = origin @ np.array([[np.cos(small), -np.sin(small)], [np.sin(small), np.cos(small)]]).T
    assert turned_with_mesh(mesh, origin, v, start, size, up) is start
