"""Size flattening (``adaproj_edge/warp/flatten.py``): a warp composed with a
holomorphic map keeps its angles and loses the harmonic part of its log size.

The ground truth here is built without the module: content on a grid shown on the flat
piece of surface a known holomorphic map ``G`` makes of it (so the warp keeps angles,
and its log size is ``log|G'|``, a harmonic function of the content position), and
the per-triangle Jacobians computed from scratch.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.warp.flatten import MAX_SCALE_LOG, flattened, harmonic_fit


def _grid(n: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n*n, 2) of a unit square grid and its triangles (T, 3)."""
    ax = np.linspace(-1.0, 1.0, n)
    xx, yy = np.meshgrid(ax, ax)
    v = np.stack([xx.ravel(), yy.ravel()], axis=1)
    k = np.arange(n * n).reshape(n, n)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel()
    tris = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return v, tris


def _jacobian_measures(content: np.ndarray, surface: np.ndarray, tris: np.ndarray):
    """Angle error and log size of each triangle's map content -> surface (both (n, 2))."""
    out_angle, out_size = [], []
    for t in tris:
        c = content[t[1:]] - content[t[0]]
        s = surface[t[1:]] - surface[t[0]]
        j = s.T @ np.linalg.inv(c.T)
        s1, s2 = np.linalg.svd(j, compute_uv=False)
        out_angle.append(s1 / s2 - 1.0)
        out_size.append(0.5 * np.log(s1 * s2))
    return np.array(out_angle), np.array(out_size)


def _warped_by(coef: tuple[complex, complex], v: np.ndarray) -> np.ndarray:
    """``v`` moved by G with G'(z) = exp(c1 z + c2 z^2), G(0) = 0 (fine quadrature)."""
    z = v[:, 0] + 1j * v[:, 1]
    s = np.linspace(0.0, 1.0, 2001)
    integrand = np.exp(coef[0] * (s[None] * z[:, None]) + coef[1] * (s[None] * z[:, None]) ** 2)
    g = z * np.trapezoid(integrand, s, axis=1)
    return np.stack([g.real, g.imag], axis=1)


coefs = st.complex_numbers(max_magnitude=0.5, allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None)
@given(c1=coefs, c2=coefs)
def test_a_harmonic_size_spread_is_removed_and_angles_kept(c1: complex, c2: complex) -> None:
    content, tris = _grid()
    surface = _warped_by((c1, c2), content)  # a flat surface the content maps to by G
    angle0, log_size = _jacobian_measures(content, surface, tris)
    # (G is holomorphic: the warp keeps angles up to the mesh's linear triangles, and
    # cancelling G's size leaves a similarity of the surface)
    weight = np.ones(len(tris))
    flat = flattened(SimpleNamespace(tris=tris), content, log_size, weight)  # type: ignore[arg-type]
    assert flat is not None
    angle, size = _jacobian_measures(flat, surface, tris)
    assert np.std(size) < 0.05 * np.std(log_size) + 1e-4, (np.std(size), np.std(log_size))
    assert angle.mean() <= angle0.mean() + 1e-3


def test_only_the_weighted_triangles_are_fitted() -> None:
    content, tris = _grid()
    surface = _warped_by((0.4 + 0.2j, 0.0), content)
    _, log_size = _jacobian_measures(content, surface, tris)
    centroids = surface[tris].mean(axis=1)
    left = (centroids[:, 0] < -0.2).astype(float)
    rng = np.random.default_rng(3)
    noisy = log_size.copy()
    noisy[left == 0] += rng.normal(0.0, 1.0, np.count_nonzero(left == 0))  # ignored
    flat = flattened(SimpleNamespace(tris=tris), content, noisy, left)  # type: ignore[arg-type]
    assert flat is not None
    _, size = _jacobian_measures(flat, surface, tris)
    assert np.std(size[left > 0]) < 0.05 * np.std(log_size[left > 0])


def test_nothing_to_fit_or_too_large_a_rescaling_gives_none() -> None:
    surface, tris = _grid(8)
    mesh = SimpleNamespace(tris=tris)
    zero = np.zeros(len(tris))
    assert flattened(mesh, surface, zero, zero) is None  # type: ignore[arg-type]
    few = zero.copy()
    few[:3] = 1.0
    assert flattened(mesh, surface, zero, few) is None  # type: ignore[arg-type]
    # a log size rising by 8 across the mesh: cancelling it would rescale it e^4-fold
    steep = 4.0 * surface[tris].mean(axis=1)[:, 0]
    assert 4.0 > MAX_SCALE_LOG
    assert flattened(mesh, surface, steep, np.ones(len(tris))) is None  # type: ignore[arg-type]


def test_a_constant_size_is_left_as_it_is() -> None:
    surface, tris = _grid(10)
    flat = flattened(
        SimpleNamespace(tris=tris), surface, np.full(len(tris), 0.3), np.ones(len(tris))
    )  # type: ignore[arg-type]
    assert flat is not None
    np.testing.assert_allclose(flat, surface, atol=1e-9)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_the_fit_recovers_a_harmonic_polynomial(degree: int) -> None:
    rng = np.random.default_rng(degree)
    z = rng.normal(size=200) + 1j * rng.normal(size=200)
    a = rng.normal(size=degree) + 1j * rng.normal(size=degree)
    w = rng.uniform(0.5, 2.0, 200)
    fit = harmonic_fit(z, np.zeros(200), w, degree)
    assert fit is not None
    z0, s, _ = fit
    zeta = (z - z0) / s
    values = 0.7 + sum(a[k] * zeta ** (k + 1) for k in range(degree)).real
    fit = harmonic_fit(z, values, w, degree)
    assert fit is not None
    np.testing.assert_allclose(fit[2], a, atol=1e-9)
