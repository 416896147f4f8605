"""Never dark: a surface the warp cannot be made on as measured goes down the chain
(content-free, repaired, the dominant plane's keystone) instead of showing nothing, and a
mesh piece joined to the rest only through a vertex is left out.

The surfaces are a level-ish floor and a wall seen on the warp grid's own lattice, with
the faults real depth has: a flying pixel on the border, pieces that touch at a corner,
a third of the nodes flying, speckle. Each warp shown is checked against the plane's own
coordinates, computed here from the true plane: on a plane the right warp is a
similarity of them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.analytic import Plane, ray_cast
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import FAST, WarpSettings
from adaproj_edge.warp.fallback import Solved, chain_of, keystone_surface, repair
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.orientation import fold_count
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner, compute_warp
from adaproj_edge.warp.solve import solve_conformal, solve_content_free
from adaproj_edge.warp.warpmap import Grid, Warp

SIZE = (640, 400)
P = Projector.default()
GRID = Grid()
PITCH = np.deg2rad(50.0)  # the device looks 50 deg down at the floor
UP = (0.0, -float(np.cos(PITCH)), -float(np.sin(PITCH)))  # gravity's up in frame P
FLOOR = Plane("floor", UP, -1.2)  # 1.2 m under the projector
WALL = Plane("wall", (0.0, 0.0, -1.0), -1.5)


def _subject() -> np.ndarray:
    m = np.zeros((40, 64), np.float32)
    m[10:30, 20:40] = 1.0
    return m


def _nodes(plane: Plane) -> np.ndarray:
    """The plane's points at the grid's vertices (21, 21, 3): the surface lattice."""
    return ray_cast(plane, np.zeros(3), P.rays(GRID.vertices(P)))


def _surface(points: np.ndarray) -> Surface:
    return Surface(points.astype(np.float32), P)


def _similarity_residual(warp: Warp, plane: Plane) -> float:
    """The largest distance (content px) of a shown vertex from the best similarity of
    the true plane's own coordinates at that vertex (either handedness)."""
    n = np.asarray(plane.normal)
    e1 = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    truth = _nodes(plane).reshape(-1, 3)
    shown = np.isfinite(warp.image_xy.reshape(-1, 2)).all(axis=1)
    xy = warp.image_xy.reshape(-1, 2)[shown]
    z_img = xy[:, 0] + 1j * xy[:, 1]
    z = truth[shown] @ e1 + 1j * (truth[shown] @ e2)
    best = np.inf
    for zz in (z, np.conj(z)):
        a = np.stack([zz, np.ones_like(zz)], axis=1)
        coef = np.linalg.lstsq(a, z_img, rcond=None)[0]
        best = min(best, float(np.abs(a @ coef - z_img).max()))
    return best


def _flying_border_pixel() -> Surface:
    """A smooth floor whose second border vertex is a flying pixel (at 0.6 of its depth:
    on the view ray, between the projector and the floor): its triangles fold."""
    pts = _nodes(FLOOR)
    pts[0, 1] *= 0.6
    return _surface(pts)


def test_a_flying_pixel_on_a_floor_is_repaired_not_rejected() -> None:
    """One folded triangle costs the cells around it, never the whole warp (it raised
    "the warp folds over; the surface is too irregular for this grid")."""
    s = _flying_border_pixel()
    for cmap in (None, _subject()):
        warp = compute_warp(s, SIZE, cmap, WarpSettings(up=UP))
        step, down = chain_of(warp)
        assert step == "repaired" and "content-free" in [d[0] for d in down]
        assert fold_count(warp) == 0
        assert np.isnan(warp.image_xy[0, 1]).all()  # the flying pixel is not shown
        shown = np.isfinite(warp.image_xy[..., 0]).mean()
        assert shown > 0.97  # a notch at the border, the rest of the floor
        assert _similarity_residual(warp, FLOOR) < 0.5


def test_the_device_and_the_cli_warp_the_same_surfaces() -> None:
    """The device's planner (coarse to fine, cached content-free step) ends at the same
    step of the chain as ``compute_warp`` (the CLI), and both show a picture."""
    s = _flying_border_pixel()
    cli = compute_warp(s, SIZE, _subject(), WarpSettings(up=UP))
    device = WarpPlanner(P, GRID, PlanSettings(refine_factor=2, warm_start=True))
    settings = WarpSettings(up=UP)
    start = device.content_free(s, SIZE, settings)
    from adaproj_edge.content.contentmap import ContentMap

    shown = device.refine(s, ContentMap(_subject(), SIZE, settings.threshold), settings, start)
    assert chain_of(shown)[0] == chain_of(cli)[0] == "repaired"
    assert fold_count(shown) == 0


def _vertex_joined() -> Surface:
    """A wall seen where the nodes of two blocks are valid: a large one (rows 5-20,
    columns 0-12) and a small one above it (rows 0-5, columns 12-16) whose triangles
    meet the large one's only at the vertex (5, 12)."""
    r, c = np.mgrid[0:21, 0:21]
    ok = ((r <= 5) & (c >= 12) & (c <= 16)) | ((r >= 5) & (c <= 12))
    return _surface(np.where(ok[..., None], _nodes(WALL), np.nan))


def test_a_piece_joined_through_a_vertex_is_a_piece_of_its_own() -> None:
    """The mesh is the largest edge-connected piece: the small block, free to turn about
    the shared vertex, is left out (it was kept and shown 650 px off the wall's
    similarity, or the system was singular)."""
    s = _vertex_joined()
    mesh = MeshGeometry.build(s, GRID)
    assert mesh.n == 16 * 13  # the large block's vertices alone
    warp = compute_warp(s, SIZE, None, WarpSettings(adaptive=False))
    assert chain_of(warp)[0] == "content-free"
    assert np.isnan(warp.image_xy[:5, 13:17]).all()
    assert _similarity_residual(warp, WALL) < 0.5


def test_a_surface_no_mesh_warp_holds_shows_the_dominant_plane() -> None:
    """A third of the floor's nodes flying: too many folds to repair; the keystone of the
    dominant plane is shown, and it is the floor's own similarity (the flying nodes are
    outliers to the plane). The chain names the content-aware step first: the conformal
    warp folds, and its placement (a rectangle holding one vertex here) reading nothing
    salient is no reason to skip the step (it was skipped, or not, by where that vertex
    fell)."""
    rng = np.random.default_rng(0)
    pts = _nodes(FLOOR)
    fly = rng.random(pts.shape[:2]) < 0.3
    pts[fly] *= rng.uniform(0.3, 0.7, (int(fly.sum()), 1))
    s = _surface(pts)
    warp = compute_warp(s, SIZE, _subject(), WarpSettings(up=UP))
    step, down = chain_of(warp)
    assert step == "keystone"
    assert [d[0] for d in down] == ["content-aware", "content-free", "repaired"]
    assert np.isfinite(warp.image_xy[..., 0]).mean() > 0.9
    assert _similarity_residual(warp, FLOOR) < 0.5
    plane = keystone_surface(s).points
    assert np.isfinite(plane).all()  # the floor's flying nodes are the plane's
    assert np.abs(plane @ np.asarray(FLOOR.normal) - FLOOR.d).max() < 1e-4


def test_speckle_alone_gives_no_warp_with_every_reason() -> None:
    """Depth on every other node in a checkerboard: no triangle, no planar piece. The
    planner raises one WarpError naming every step it tried (the app keeps the last
    good picture)."""
    pts = _nodes(WALL)
    r, c = np.mgrid[0:21, 0:21]
    pts[(r + c) % 2 == 1] = np.nan
    with pytest.raises(WarpError) as e:
        compute_warp(_surface(pts), SIZE, None, WarpSettings())
    for step in ("content-free:", "repaired:", "keystone:"):
        assert step in str(e.value)


def test_a_repair_starts_from_the_folded_solve_instead_of_solving_it_again() -> None:
    """The chain's content-free step has solved the whole mesh when it finds the fold;
    the repair starts from that solve (it solved it again: three content-free solves
    where two do, on every frame that goes down the chain) and ends where a repair
    from scratch ends (the same function on the same mesh: the same bits)."""
    s = _flying_border_pixel()
    solves: list[int] = []

    def content_free(
        mesh: MeshGeometry, v_conf: np.ndarray, lam: float
    ) -> tuple[np.ndarray, np.ndarray]:
        solves.append(mesh.n)
        return solve_content_free(mesh, v_conf, lam)

    planner = WarpPlanner(P, GRID, backend=replace(FAST, content_free=content_free))
    start = planner.content_free(s, SIZE, WarpSettings(up=UP))
    assert chain_of(start.warp)[0] == "repaired" and fold_count(start.warp) == 0
    assert len(solves) == 2  # the whole mesh (it folds), then the mesh without the notch
    lam = WarpSettings().lam
    mesh = MeshGeometry.build(s, GRID)
    v_conf = solve_conformal(mesh)
    first = Solved(mesh, v_conf, solve_content_free(mesh, v_conf, lam)[0])
    again = repair(s, GRID, None, solve_conformal, solve_content_free, lam)
    resumed = repair(s, GRID, None, solve_conformal, solve_content_free, lam, first)
    assert resumed.dropped == again.dropped > 0
    assert np.array_equal(resumed.v, again.v)
