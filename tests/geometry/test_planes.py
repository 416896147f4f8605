"""Walls snapped onto their planes (geometry/planes.py), against analytic ground truth:
noisy lattices of the analytic surfaces, ray-cast independently of the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import SurfaceError
from adaproj_edge.geometry.analytic import Corner, get_surface, ray_cast
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.planes import (
    PLANES_KEY,
    curvature_ratio,
    find_planes,
    on_planes,
    plane_equations,
    snap_planes,
)
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface

NOISE_M = 0.0015  # about what 3 averaged stereo frames leave on the lattice at 1.5-2 m
P = Projector.default()


def truth(surface: str | Corner, shape: tuple[int, int]) -> FloatArray:
    s = get_surface(surface) if isinstance(surface, str) else surface
    return ray_cast(s, np.zeros(3), P.rays(lattice_uv(P, shape)))


def noisy(surface: str | Corner, seed: int, shape: tuple[int, int] = (21, 21)) -> Surface:
    """The lattice with depth noise along each ray (as stereo has it)."""
    pts = truth(surface, shape)
    rng = np.random.default_rng(seed)
    z = pts[..., 2] + rng.normal(scale=NOISE_M, size=pts.shape[:2])
    rays = P.rays(lattice_uv(P, shape))
    return Surface((rays * z[..., None]).astype(np.float32), P)


CONVEX_CORNER = Corner("corner-convex", x0=-0.1, z0=1.6, concave=False)


@pytest.mark.parametrize("corner", ["corner", CONVEX_CORNER], ids=["concave", "convex"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_wall_corner_becomes_its_two_walls(corner: str | Corner, seed: int) -> None:
    s = noisy(corner, seed)
    snapped, planes = snap_planes(s)
    assert len(planes) == 2
    assert snapped.shape == (161, 161)  # 8x finer: the crease lies where it is
    want = truth(corner, snapped.shape)
    got = snapped.points.astype(np.float64)
    err = np.abs(got[..., 2] - want[..., 2])
    ok = np.isfinite(err)
    assert ok.mean() > 0.95
    # the noise is gone on the walls (the frame's outer ring of cells stays interpolated)
    inner = err[4:-4, 4:-4]
    assert np.nanmedian(inner) < 0.25 * NOISE_M, np.nanmedian(inner)
    assert np.nanpercentile(inner, 95) < 0.6 * NOISE_M, np.nanpercentile(inner, 95)
    # every node stays on its own projector ray
    uv = P.project(got)
    assert np.allclose(uv[ok], lattice_uv(P, snapped.shape)[ok], atol=1e-3)
    # the meta lists the two planes (for the warp), and the snapped walls lie on them
    eq = plane_equations(snapped.meta)
    assert np.allclose(eq, [[*p.normal, p.offset] for p in planes])
    on = on_planes(got[4:-4, 4:-4].reshape(-1, 3), eq)
    assert on.any(axis=1).mean() > 0.9


@pytest.mark.parametrize(
    "bad", ["walls", [[0.0, 0.0, 1.0]], [[0.0, 0.0, 2.0, 1.0]], [[0, 0, 1, None]]]
)
def test_a_surface_whose_meta_lists_malformed_planes_is_refused(bad: object) -> None:
    with pytest.raises(SurfaceError, match=PLANES_KEY):
        plane_equations({PLANES_KEY: bad})
    assert plane_equations({}).shape == (0, 4)


@pytest.mark.parametrize(
    "name", ["cylinder-convex", "cylinder-concave", "sphere-convex", "sphere-concave", "bowl"]
)
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("sensor", [None, "oak-d"])
def test_curved_surfaces_are_left_as_they_are(name: str, seed: int, sensor: str | None) -> None:
    """Also with the sensor's noise model, which lets a plane's nodes lie a part of a
    depth step and of the sensor's slow error away from it."""
    s = noisy(name, seed)
    model = None if sensor is None else SensorModel.of(Calibration.default().depth, sensor)
    snapped, planes = snap_planes(s, sensor=model)
    assert planes == [] and snapped is s


@pytest.mark.parametrize("name", ["plane", "tilted"])
def test_a_plane_is_one_plane(name: str) -> None:
    s = noisy(name, 7)
    planes = find_planes(s)
    assert len(planes) == 1
    assert planes[0].nodes.mean() > 0.9
    # its normal is the analytic one (to a fraction of a degree)
    t = truth(name, (21, 21)).reshape(-1, 3)
    c = t.mean(axis=0)
    n_true = np.linalg.svd(t - c)[2][-1]
    assert abs(float(planes[0].normal @ n_true)) > np.cos(np.deg2rad(0.3))


def test_curvature_ratio_tells_a_noisy_plane_from_a_gentle_bend() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-0.2, 0.2, (2, 400))
    flat = np.stack([a, b, 1.5 + rng.normal(scale=0.0015, size=400)], axis=1)
    bent = flat + np.stack([0 * a, 0 * b, 0.004 * (a / 0.2) ** 2], axis=1)  # 4 mm sag
    n, d = np.array([0.0, 0.0, -1.0]), -1.5
    assert curvature_ratio(flat, n, d) < 1.1
    assert curvature_ratio(bent, n, d) > 1.5


def test_holes_and_tiny_lattices_do_not_break_it() -> None:
    s = noisy("corner", 4)
    pts = s.points.copy()
    pts[5:9, 3:12] = np.nan  # a hole in one wall
    pts[:, :2] = np.nan  # the frame's edge unseen
    snapped, planes = snap_planes(Surface(pts, P))
    assert len(planes) == 2
    assert np.isfinite(snapped.points).all(axis=-1).mean() > 0.8
    tiny = noisy("plane", 5, (3, 3))
    assert snap_planes(tiny)[1] == []  # too small to fit a window: nothing found
    empty = Surface(np.full((21, 21, 3), np.nan, np.float32), P)
    assert snap_planes(empty) == (empty, [])
