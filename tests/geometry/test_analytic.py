"""The analytic surfaces are exact ground truth: every hit lies on the surface (its own
equation, written here again), no earlier hit is missed, and the smooth patches are
named right. Independent of the warp engine."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.analytic import (
    DEVELOPABLE,
    FINE_DETAIL,
    NON_DEVELOPABLE,
    SURFACES,
    ConeWall,
    CylinderFloor,
    get_surface,
    ray_cast,
    simulate_surface,
)
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.relief import Bumps, Waves

P = Projector.default()


def rays(step: int = 16) -> FloatArray:
    ys, xs = np.mgrid[0 : P.height : step, 0 : P.width : step].astype(np.float64)
    return P.rays(np.stack([xs, ys], axis=-1)).reshape(-1, 3)


def residual(name: str, X: FloatArray) -> FloatArray:
    """How far points X (N, 3) are from the surface, by its equation (metres)."""
    s = get_surface(name)
    if isinstance(s, Bumps | Waves):
        c, sn = np.cos(s.yaw), np.sin(s.yaw)
        u = c * X[:, 0] - sn * (X[:, 2] - s.z0)
        v = X[:, 1]
        w = sn * X[:, 0] + c * (X[:, 2] - s.z0)
        if isinstance(s, Waves):
            phase = 2 * np.pi * (u * np.cos(s.direction) + v * np.sin(s.direction)) / s.wavelength
            h = s.amplitude * np.sin(phase)
        else:
            h = np.zeros_like(u)
            for bu, bv, sigma, a in s.bumps:
                h += a * np.exp(-((u - bu) ** 2 + (v - bv) ** 2) / (2 * sigma**2))
        out: FloatArray = np.abs(w - h)
        return out
    if isinstance(s, CylinderFloor):
        wall = np.abs(np.hypot(X[:, 0] - s.cx, X[:, 2] - s.cz) - s.r)
        return np.minimum(wall, np.abs(X[:, 1] - s.floor))
    if isinstance(s, ConeWall):
        lean = np.array([np.sin(s.turn), 0.0, np.cos(s.turn)])
        axis = np.cos(s.alpha) * np.array([0.0, 1.0, 0.0]) + np.sin(s.alpha) * lean
        d = X - np.array([s.x0, s.apex_y, s.z0])
        cone = np.abs(d @ axis - np.cos(s.alpha) * np.linalg.norm(d, axis=1))
        return np.where(X[:, 0] <= s.x0 + 1e-12, np.abs(X[:, 2] - s.z0), cone)
    raise AssertionError(name)


@pytest.mark.parametrize("name", ["cylinder-floor", "cone-wall", "bumps", "waves", "waves-fine"])
def test_hits_lie_on_the_surface(name: str) -> None:
    X = ray_cast(get_surface(name), np.zeros(3), rays())
    ok = np.isfinite(X).all(axis=1)
    assert ok.mean() > 0.8
    assert residual(name, X[ok]).max() < 1e-9


@pytest.mark.parametrize("name", ["bumps", "waves", "waves-fine"])
def test_relief_has_no_earlier_hit(name: str) -> None:
    # march along each ray in steps far below the relief's scale: the surface is first
    # crossed where the cast says
    s = get_surface(name)
    d = rays(40)
    t = s.intersect(np.zeros_like(d), d)
    X = d * t[:, None]
    # every point of the ray before the hit is on the projector's side of the relief
    c, sn = np.cos(s.yaw), np.sin(s.yaw)
    for frac in np.linspace(0.5, 0.9999, 40):
        Y = d * (t * frac)[:, None]
        w = sn * Y[:, 0] + c * (Y[:, 2] - s.z0)
        u = c * Y[:, 0] - sn * (Y[:, 2] - s.z0)
        h = np.zeros_like(u)
        if isinstance(s, Waves):
            h = s.amplitude * np.sin(
                2 * np.pi * (u * np.cos(s.direction) + Y[:, 1] * np.sin(s.direction)) / s.wavelength
            )
        else:
            assert isinstance(s, Bumps)
            for bu, bv, sigma, a in s.bumps:
                h += a * np.exp(-((u - bu) ** 2 + (Y[:, 1] - bv) ** 2) / (2 * sigma**2))
        assert np.all(w < h + 1e-12)
    assert np.isfinite(X).all()


def test_relief_casts_from_moved_origins() -> None:
    # the session simulator casts from a hand-held pose: origins off zero, rays turned
    s = get_surface("bumps")
    rng = np.random.default_rng(4)
    d = rays(32)
    a = 0.1
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    o = np.broadcast_to(rng.normal(scale=0.05, size=3), d.shape)
    t = s.intersect(o, d @ R.T)
    X = o + t[:, None] * (d @ R.T)
    ok = np.isfinite(X).all(axis=1)
    assert ok.mean() > 0.9 and residual("bumps", X[ok]).max() < 1e-9


def test_the_floor_runs_under_the_wall_and_meets_it_along_a_curve() -> None:
    s = get_surface("cylinder-floor")
    assert isinstance(s, CylinderFloor)
    surf = simulate_surface("cylinder-floor", step=8)
    X = surf.points.astype(np.float64)
    label = s.patch(X)
    assert set(np.unique(label)) == {0, 1}
    # the junction: the lowest wall row in each column varies across the frame
    wall_rows = [np.flatnonzero(label[:, c] == 0).max() for c in range(0, label.shape[1], 10)]
    assert max(wall_rows) - min(wall_rows) >= 3


def test_the_cone_meets_the_wall_along_a_straight_ruling() -> None:
    s = get_surface("cone-wall")
    assert isinstance(s, ConeWall)
    surf = simulate_surface("cone-wall", step=8)
    X = surf.points.reshape(-1, 3).astype(np.float64)
    X = X[np.isfinite(X).all(axis=1)]
    label = s.patch(X)
    on_wall = X[label == 0]
    assert np.allclose(on_wall[:, 2], s.z0, atol=1e-6)
    near = X[np.abs(X[:, 0] - s.x0) < 0.004]
    assert np.allclose(near[:, 2], s.z0, atol=0.002)  # the two pieces meet: no step


def test_the_registry_sorts_the_surfaces() -> None:
    assert set(DEVELOPABLE) | set(NON_DEVELOPABLE) | set(FINE_DETAIL) == set(SURFACES)
    assert "waves" in FINE_DETAIL and "bumps" in FINE_DETAIL and "cylinder-floor" in FINE_DETAIL
    assert "cone-wall" in DEVELOPABLE
    assert get_surface("waves").developable and not get_surface("bumps").developable
