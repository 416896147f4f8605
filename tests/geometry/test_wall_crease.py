"""A crease between two snapped walls unfolds about the walls' own line.

The corner is known in closed form (:class:`~adaproj_edge.geometry.analytic.Corner`):
its walls' equations are computed here from its definition, listed in the surface's
meta as snapping lists them, and the surface is the corner's points on a lattice of
16 projector pixels (so the lattice's interpolant cuts the crease, as sensed depth's
does).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry import creases
from adaproj_edge.geometry.analytic import Corner, get_surface, simulate_surface
from adaproj_edge.render.seams import grid_unfolding
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.warpmap import Grid


def corner_walls(corner: Corner) -> FloatArray:
    """The corner's two walls (2, 4) ``[n, d]``, ``n . X = d``: each contains the
    vertical crease through (x0, ., z0) and its horizontal direction."""
    a = corner.half_angle
    walls = []
    for side in (-1.0, 1.0):
        n = np.array([np.cos(a), 0.0, side * np.sin(a)])  # (across (side sin a, 0, -cos a))
        walls.append([*n, float(n @ [corner.x0, 0.0, corner.z0])])
    return np.array(walls)


def test_a_crease_between_snapped_walls_is_their_line_without_a_search(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # before, each crease triangle's sides were fitted as patches through the
    # interpolant (40 tries at 20x20) and unfolded about a line 4 mm off the crease
    corner = get_surface("corner")
    assert isinstance(corner, Corner) and corner.concave and corner.half_angle == np.pi / 4
    walls = corner_walls(corner)
    exact = simulate_surface(corner, step=16)
    sensed = replace(exact, meta={"source": "depth", "plane_equations": walls.tolist()})

    def searched(*args: Any) -> Any:
        raise AssertionError("the sides' patches were searched for")

    monkeypatch.setattr(creases, "ruled_planes", searched)
    mesh = MeshGeometry.build(sensed, Grid(20, 20))
    depth = mesh.points[:, 2].reshape(mesh.grid_uv.shape[:2])
    shown = grid_unfolding(mesh.grid_uv, depth, exact.projector, sensed)
    assert mesh.ruled.any() and np.array_equal(shown.ruled, shown.folded)
    f = np.flatnonzero(shown.folded)
    # the walls' normals facing the projector (d < 0), copied: to a rounding
    facing = walls[:, :3] * np.where(walls[:, 3] > 0, -1.0, 1.0)[:, None]
    for normals in (shown.normal_a[f], shown.normal_b[f]):
        off = np.min(np.linalg.norm(normals[:, None] - facing[None], axis=2), axis=1)
        assert off.max() <= 1e-12
    assert np.all(np.abs(np.einsum("fj,fj->f", shown.normal_a[f], shown.normal_b[f])) < 1e-12)
    # each rotates about the crease x = x0, z = z0 (to 1e-9 m: two 3x3 solves' rounding
    # at ~2 m, with a condition number of a few, is ~1e-15 m; the 4 mm of before fail)
    assert np.abs(shown.origin[f][:, [0, 2]] - [corner.x0, corner.z0]).max() <= 1e-9
    # ... by the walls' angle: a point of wall b 5 cm off the crease lands on wall a
    line = np.cross(shown.normal_a[f], shown.normal_b[f])
    b_pts = shown.point_b[f] + 0.05 * np.cross(shown.normal_b[f], line)
    off_a = np.einsum(
        "fj,fj->f", shown.unfold_points(f, b_pts) - shown.point_a[f], shown.normal_a[f]
    )
    assert np.abs(off_a).max() <= 1e-9


def test_walls_that_do_not_meet_across_a_triangle_are_not_its_crease() -> None:
    # the same lattice with the second wall listed 0.3 m farther: the walls still meet,
    # far from every triangle, so the crease is left to the corners' planes as before
    corner = get_surface("corner")
    assert isinstance(corner, Corner)
    walls = corner_walls(corner)
    walls[1, 3] += 0.3
    exact = simulate_surface(corner, step=16)
    sensed = replace(exact, meta={"source": "depth", "plane_equations": walls.tolist()})
    mesh = MeshGeometry.build(sensed, Grid(20, 20))
    assert mesh.folded.any() and not mesh.ruled.any()
