"""The curvature bound (``tests/curvature_bound.py``) against a case known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from adaproj_edge.geometry.analytic import Sphere, get_surface
from adaproj_edge.geometry.projector import Projector
from tests.curvature_bound import curvature_bound
from tests.distortion import surface_points

CENTRE = np.array([0.0, 0.0, 2.0])  # on the projector's axis
R = 0.6
PX = 1.5e-3  # metres of the stereographic plane per content pixel
CONTENT = (640, 400)


def _stereographic_map(step: int) -> tuple[NDArray[np.float32], Sphere]:
    """A convex sphere on the projector's axis and, at every ``step``-th projector pixel
    (NaN elsewhere), the content position its surface point has in stereographic
    coordinates from the sphere's far pole (an exactly conformal chart), in pixels
    centred on the content."""
    sphere = Sphere("cap", tuple(CENTRE), R, concave=False)
    p = Projector.default()
    gx, gy = np.meshgrid(np.arange(0, p.width, step), np.arange(0, p.height, step))
    uv = np.stack([gx, gy], axis=-1).astype(np.float64)
    y = surface_points(sphere, p.K, uv) - CENTRE
    with np.errstate(invalid="ignore"):  # NaN past the silhouette (the frame's corners)
        z = R * (y[..., 0] + 1j * y[..., 1]) / (R - y[..., 2])  # metres, from pole (0, 0, R)
    m = np.full((p.height, p.width, 2), np.nan, dtype=np.float32)
    m[gy, gx, 0] = z.real / PX + CONTENT[0] / 2
    m[gy, gx, 1] = z.imag / PX + CONTENT[1] / 2
    return m, sphere


@pytest.mark.parametrize("radius", [60.0, 110.0])
def test_the_bound_on_a_spherical_cap_is_the_stereographic_log_size_spread(radius: float) -> None:
    """On a disc of stereographic coordinates (a spherical cap seen along its axis) the
    log size ``u = log(2 R^2 / (R^2 + |z|^2))`` is radial, and so are the scorer's
    weights (each projector-lattice triangle alike, the view being symmetric about the
    axis): every non-constant harmonic ``r^k cos(k t)``, ``r^k sin(k t)`` is orthogonal
    to a radial function under radial weights, so the best harmonic fit is a constant
    and the least spread is the std of ``u`` itself over the same triangles, computed
    here from the closed form, not from the curvature.

    Tolerance: the bound sums each 12-px triangle's ``K dA`` as a point charge at its
    centroid (a midpoint rule for the logarithmic potential), whose error relative to
    the potential's variation over the cap is of order ``(h / L)^2`` with ``h`` = 12 px
    and ``L`` the cap's radius in projector pixels (220 and 370 px here): 0.3 % at
    most, so 1 % (measured: 0.05 % and 0.03 %); the exact side is taken over the same
    triangles' centroids, so no sampling differs."""
    step = 12
    m, sphere = _stereographic_map(step)
    h, w = CONTENT[1], CONTENT[0]
    yy, xx = np.mgrid[0:h, 0:w]
    mask = (np.hypot(xx - w / 2, yy - h / 2) <= radius).astype(np.float32)
    p = Projector.default()
    got = curvature_bound(m, sphere, p.K, mask, step=step)
    # the exact u at the chart position of each triangle's content centroid, the
    # triangles selected by that centroid as the bound selects them
    gx, gy = np.meshgrid(np.arange(0, p.width, step), np.arange(0, p.height, step))
    c = m[gy, gx].astype(np.float64)
    vals = []
    r, k = gx.shape
    for tri in (((0, 0), (0, 1), (1, 1)), ((0, 0), (1, 1), (1, 0))):
        sl = [(slice(a, a + r - 1), slice(b, b + k - 1)) for a, b in tri]
        cent = sum(c[s] for s in sl).reshape(-1, 2) / 3
        zc = (cent[:, 0] - w / 2) * PX + 1j * (cent[:, 1] - h / 2) * PX
        ok = np.isfinite(cent).all(1)
        ci = np.clip(np.rint(np.where(ok[:, None], cent, 0)).astype(int), 0, [w - 1, h - 1])
        keep = ok & (mask[ci[:, 1], ci[:, 0]] >= 0.5)
        vals.append(np.log(2 * R * R / (R * R + np.abs(zc[keep]) ** 2)))
    exact = float(np.std(np.concatenate(vals)))
    assert exact > 0.005  # a cap curved enough to tell
    assert got == pytest.approx(exact, rel=0.01), (got, exact)


def test_the_bound_is_zero_on_a_developable_surface() -> None:
    """No curvature, no size spread: an unrolling of a cylinder keeps size exactly."""
    s = get_surface("cylinder-convex")
    p = Projector.default()
    m, _ = _stereographic_map(12)  # any chart: no charge anywhere
    yy, xx = np.mgrid[0 : CONTENT[1], 0 : CONTENT[0]]
    mask = (np.hypot(xx - CONTENT[0] / 2, yy - CONTENT[1] / 2) <= 110).astype(np.float32)
    assert curvature_bound(m, s, p.K, mask, step=12) == pytest.approx(0.0, abs=1e-12)
