"""The ground-truth scorer (tests/distortion.py) itself: its closed-form singular values
agree with an SVD, and the rays it keeps per surface and frame are those of the surface
and frame asked for."""

from __future__ import annotations

import cv2
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


def _every_triangle_filled(map_xy: np.ndarray, size: tuple[int, int]) -> float:
    """visible_fraction as first written: every finite triangle filled."""
    w, h = size
    canvas = np.zeros((h, w), dtype=np.uint8)
    m = map_xy.reshape(-1, 2)
    m = m[np.isfinite(m).all(axis=1)]
    canvas[np.clip(np.rint(m[:, 1]).astype(int), 0, h - 1),
           np.clip(np.rint(m[:, 0]).astype(int), 0, w - 1)] = 1  # fmt: skip
    g = map_xy.astype(np.float64)
    quads = [g[:-1, :-1], g[:-1, 1:], g[1:, 1:], g[1:, :-1]]
    for tri in ((0, 1, 2), (0, 2, 3)):
        pts = np.stack([quads[k] for k in tri], axis=2).reshape(-1, 3, 2)
        pts = pts[np.isfinite(pts).all(axis=(1, 2))]
        q = np.rint(pts * 16).astype(np.int32)
        cv2.fillPoly(canvas, list(q), 1, lineType=cv2.LINE_8, shift=4)
    return float(canvas.mean())


def test_visible_fraction_fills_what_filling_every_triangle_fills() -> None:
    """Leaving out the triangles the projector's pixels already cover changes nothing:
    maps shrinking and magnifying the content, with holes, a fold and overlaps, each
    equal to filling every triangle (the same pixels are counted: exactly equal)."""
    rng = np.random.default_rng(3)
    v, u = np.mgrid[0:90, 0:140].astype(np.float64)
    for scale in (0.6, 1.0, 2.5):
        m = np.stack([u, v], axis=-1) * scale + rng.normal(scale=0.3, size=(90, 140, 2))
        m[20:26, 30:50] = np.nan
        m[40:60, 60:90, 0] = m[40:60, 60:90, 0][:, ::-1]  # a fold
        m[70:80, 10:40] = m[70:80, 10:40] * 1.7 - 15  # overlapping the rest
        size = (int(140 * scale * 0.9), int(90 * scale * 0.9))
        got = distortion.visible_fraction(m.astype(np.float32), size)
        assert got == _every_triangle_filled(m.astype(np.float32), size) and got < 1.0
