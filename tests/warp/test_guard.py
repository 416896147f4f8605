"""Never worse than conformal on the subject: the guard's measure and its choice."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.analytic import get_surface, simulate_surface
from adaproj_edge.warp.displayed import STEP, DisplaySamples
from adaproj_edge.warp.engine import WarpSettings, refine
from adaproj_edge.warp.guard import guard, guard_grid, subject_distortion, triangle_distortion
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.placement import place
from adaproj_edge.warp.solve import solve_conformal
from adaproj_edge.warp.warpmap import Grid
from tests.distortion import in_mask, measure
from tests.warp.conftest import CONTENT, subject_masks, surface, warped


@pytest.fixture(scope="module")
def sphere() -> MeshGeometry:
    return MeshGeometry.build(simulate_surface("sphere-convex", step=4), Grid(16, 12))


def test_a_plane_developed_has_no_distortion() -> None:
    mesh = MeshGeometry.build(simulate_surface("tilted", step=8), Grid(12, 8))
    v = solve_conformal(mesh)
    angle, log_size = triangle_distortion(mesh, 250.0 * v)
    assert np.abs(angle).max() < 1e-9
    assert np.ptp(log_size) < 1e-9 and log_size.mean() == pytest.approx(np.log(1 / 250.0))


def test_the_measure_counts_only_what_is_salient(sphere: MeshGeometry) -> None:
    v = solve_conformal(sphere)
    pl = place(sphere, v, CONTENT)
    none = ContentMap(np.zeros((50, 80), np.float32), CONTENT)
    assert subject_distortion(sphere, pl.apply(v), none).weight == 0
    left = ContentMap(subject_masks()["one-left"], CONTENT)
    m = subject_distortion(sphere, pl.apply(v), left)
    whole = subject_distortion(
        sphere, pl.apply(v), ContentMap(np.ones((50, 80), np.float32), CONTENT)
    )
    assert 0 < m.weight < whole.weight
    assert m.angle > 0 and m.size > 0


def test_a_worse_candidate_is_not_kept(sphere: MeshGeometry) -> None:
    v = solve_conformal(sphere)
    pl = place(sphere, v, CONTENT)
    cmap = ContentMap(subject_masks()["half"], CONTENT)
    # a sheared copy of the conformal warp: worse in angle everywhere
    sheared = v @ np.array([[1.0, 0.15], [0.0, 1.0]]).T
    choice = guard(sphere, (sheared, place(sphere, sheared, CONTENT)), (v, pl), cmap)
    assert choice.meta["choice"] in ("blend", "conformal") and choice.t < 1
    kept = subject_distortion(sphere, choice.placement.apply(choice.v), cmap)
    conf = subject_distortion(sphere, pl.apply(v), cmap)
    assert kept.angle <= conf.angle and kept.size <= conf.size + 1e-12


def test_a_better_candidate_is_kept(sphere: MeshGeometry) -> None:
    v = solve_conformal(sphere)
    pl = place(sphere, v, CONTENT)
    cmap = ContentMap(subject_masks()["one-left"], CONTENT)
    # a bent copy of the conformal warp: worse in angle and in size
    bent = v.copy()
    bent[:, 0] += 0.8 * (v[:, 0] - v[:, 0].mean()) ** 2
    choice = guard(sphere, (v, pl), (bent, place(sphere, bent, CONTENT)), cmap)
    assert choice.meta["choice"] == "content-aware" and choice.t == 1.0
    assert choice.meta["reason"] and "aware" in choice.meta and "conformal" in choice.meta


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bumps", "sphere-convex"])
def test_the_display_measure_is_what_the_display_shows(name: str) -> None:
    # the guard's measure with the surface (the full grid) against the independent
    # scorer's on the rendered per-pixel map, at the same sampling
    warp, m = warped(name, "conformal")
    s = surface(name)
    rows, cols = warp.grid_uv.shape[:2]
    mesh = MeshGeometry.build(s, Grid(cols - 1, rows - 1), grid_uv=warp.grid_uv)
    xy = warp.image_xy.reshape(-1, 2)[mesh.verts]
    display = DisplaySamples.build(mesh, s)
    for mask in ("quarter", "one-left"):
        ours = subject_distortion(mesh, xy, ContentMap(subject_masks()[mask], CONTENT), display)
        d = measure(m, get_surface(name), s.projector.K, STEP)
        d = d.select(in_mask(d, subject_masks()[mask]))
        assert ours.angle == pytest.approx(d.angle_mean, rel=0.02)
        assert ours.size == pytest.approx(d.size_std, rel=0.02)


@pytest.mark.slow
def test_the_device_guard_shows_the_flattened_warp_it_chose() -> None:
    # a large subject on a bowl: the content-aware warp's size is flattened, and the
    # grid the device displays must be that warp, not the one it was given
    s = surface("bowl")
    mesh = MeshGeometry.build(s, Grid(20, 20))
    vc = solve_conformal(mesh)
    pc = place(mesh, vc, CONTENT)
    cmap = ContentMap(subject_masks()["quarter"], CONTENT)
    # the alternation's own result, before any guard (its fixed point does not depend
    # on the start)
    va, pa, _, _ = refine(mesh, vc, pc, cmap, WarpSettings())
    rows, cols = mesh.grid_uv.shape[:2]
    given = np.full((rows * cols, 2), np.nan)
    given[mesh.verts] = pa.apply(va)
    kept, meta = guard_grid(given.reshape(rows, cols, 2), mesh, (vc, pc), cmap)
    assert meta["choice"] == "flattened", meta["choice"]
    shown = kept.reshape(-1, 2)[mesh.verts]
    assert not np.allclose(shown, given[mesh.verts])
    m_shown = subject_distortion(mesh, shown, cmap)
    m_given = subject_distortion(mesh, pa.apply(va), cmap)
    assert m_shown.size < m_given.size
    assert m_shown.size == pytest.approx(meta["flattened"]["size"], rel=1e-9)
