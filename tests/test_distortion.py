"""The ground-truth scorer (tests/distortion.py) itself: its closed-form singular values
agree with an SVD, and the rays it keeps per surface and frame are those of the surface
and frame asked for."""

from __future__ import annotations

import numpy as np

from adaproj_edge.geometry.analytic import get_surface, simulate_surface
from tests import distortion
from tests.distortion import _singular_values, measure

EPS = np.finfo(np.float64).eps


def _jacobians(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Content edges dc (n, 2, 2) and surface edges dX (n, 3, 2) (columns: edges) of
    well-shaped and thin triangles, mapped conformally, slightly anisotropically (the
    scorer's usual 1e-9..1e-1 angle error) and arbitrarily."""
    dc = rng.normal(size=(n, 2, 2))
    thin = slice(0, n // 3)
    dc[thin, :, 1] = dc[thin, :, 0] + 1e-5 * rng.normal(size=(n // 3, 2))
    det = dc[:, 0, 0] * dc[:, 1, 1] - dc[:, 0, 1] * dc[:, 1, 0]
    dc[det < 0] = dc[det < 0][:, ::-1]  # the scorer keeps det > 0 only
    frame = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0][:, :, :2]  # orthonormal columns
    stretch = np.tile(np.eye(2), (n, 1, 1)) * np.exp(rng.normal(size=n))[:, None, None]
    stretch[n // 2 :, 0, 0] *= 1 + 10 ** rng.uniform(-9, -1, size=n - n // 2)
    dX = frame @ stretch @ dc
    dX[::7] = rng.normal(size=dX[::7].shape)
    return dc, dX


def test_closed_form_singular_values_agree_with_an_svd() -> None:
    dc, dX = _jacobians(np.random.default_rng(29), 3000)
    det = dc[:, 0, 0] * dc[:, 1, 1] - dc[:, 0, 1] * dc[:, 1, 0]
    big, small = _singular_values(dX, dc, det)
    sv = np.linalg.svd(dX @ np.linalg.inv(dc), compute_uv=False)
    # J = dX inv(dc) is itself formed to ~cond(dc) eps (relative to sigma1), by either
    # path; both take singular values backward stably (a few eps * sigma1 more)
    tol = 64 * EPS * np.linalg.cond(dc) * sv[:, 0]
    assert np.all(np.abs(big - sv[:, 0]) <= tol)
    assert np.all(np.abs(small - sv[:, 1]) <= tol)
    # hence the angle error sigma1 / sigma2 - 1 agrees to about tol (1 + s1/s2) / s2
    angle_tol = tol / sv[:, 1] * (1 + sv[:, 0] / sv[:, 1])
    assert np.all(np.abs(big / small - sv[:, 0] / sv[:, 1]) <= angle_tol)


def test_rays_kept_per_surface_are_the_surface_asked_for() -> None:
    projector = simulate_surface("plane", step=16).projector
    yy, xx = np.mgrid[0 : projector.height, 0 : projector.width].astype(np.float32)
    map_xy = np.stack([0.5 * xx + 0.01 * yy, 0.5 * yy - 0.02 * xx], axis=-1)

    def scored(name: str, fresh: bool) -> distortion.Distortion:
        if fresh:
            distortion._LATTICES.clear()
        return measure(map_xy, get_surface(name), projector.K)

    sphere = scored("sphere-concave", fresh=True)
    corner = scored("corner", fresh=False)  # a second surface while the first is kept
    again = scored("sphere-concave", fresh=False)  # the first, from what was kept
    for kept, name in ((corner, "corner"), (again, "sphere-concave")):
        # the same arithmetic on the same rays: identical, not merely close
        fresh = scored(name, fresh=True)
        assert np.array_equal(kept.log_size, fresh.log_size) and kept.folds == fresh.folds
    assert np.array_equal(sphere.log_size, again.log_size)
    assert not np.array_equal(sphere.log_size, corner.log_size)  # not the first surface
