"""The least size inconsistency any angle-preserving map of a subject's footprint can
have, computed from the surface's Gaussian curvature (issue 30, "the large-subject line").

Derivation. Let ``z`` be conformal coordinates of the footprint ``S`` (for a warp, its
content coordinates: a conformal warp's are, up to its small angle error) and
``e^{2u} |dz|^2`` the surface's metric in them, so ``u`` is the log size the scorer
measures. Gauss's equation for a conformal metric is

    Laplacian_z u = -K e^{2u},

with ``K`` the Gaussian curvature. Every other angle-preserving map of ``S`` is
``w = f(z)`` with ``f`` holomorphic (``S`` is simply connected); its log size, read at
the same surface point, is ``u - log|f'(z)|``, and ``log|f'|`` is harmonic; conversely,
every harmonic ``h`` on a simply connected piece is ``log|f'|`` for ``f' = e^{h + i h*}``.
So the log sizes of all angle-preserving maps of ``S`` are exactly ``u_p + h``, ``h``
harmonic, for any one ``u_p`` with ``Laplacian u_p = -K e^{2u}``, and the least size
inconsistency is

    min over harmonic h of std(u_p + h)    (over the footprint),

which depends on the surface only through its curvature over ``S`` (zero on a
developable surface: an exact unrolling has constant size).

The source ``K e^{2u}`` is a density per unit of ``z``-area, and ``e^{2u} dA_z`` is the
surface's own area element: ``K e^{2u} dA_z = K dA_S`` is the curvature measure of the
surface carried to the chart. So no fixed point on ``u`` is needed: the surface is cast
at a fine lattice of projector pixels (analytic rays, independent of the warp's grid),
each small surface triangle's ``K dA`` (``K`` of the analytic surface at its centroid,
``dA`` its exact area) is placed at its chart position (where the map shows it), and a
particular solution is the logarithmic potential

    u_p(z) = -(1 / 2 pi) sum_j K_j A_j log|z - z_j|

(``Laplacian log|z| = 2 pi delta``; the sources outside the footprint add a harmonic
function there, so only those inside count). ``min over h`` is a weighted least-squares
fit of ``u_p`` by the harmonic polynomials ``Re z^k``, ``Im z^k`` (k <= ``degree``) on
the footprint: ``u_p`` is smooth there (degrees 4 to 18 agree within 0.1 % on the half
subjects of the sphere and the bowl). The std is taken over the same small
projector-lattice triangles, each weighted alike, as the scorer's
(``tests/distortion.py``).

Only the chart's positions enter (where the footprint lies and where each surface
triangle shows), never its derivatives: a grid warp's log size carries the grid's
discretisation noise, which a harmonic fit of it keeps as residual and so inflates
(the older ``tests/warp/bound.harmonic_residual`` on the conformal warp's log size).

Checked in closed form on a spherical cap in stereographic coordinates
(``u = log(2 R^2 / (R^2 + |z|^2))``: radial, so its best harmonic fit over a disc is a
constant and the bound is the std of ``u`` itself).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.geometry.analytic import AnalyticSurface, Bowl, Sphere
from tests.distortion import surface_points
from tests.warp.bound import harmonic_residual

FloatArray = NDArray[np.float64]
Curvature = Callable[[FloatArray], FloatArray]  # points (n, 3) -> K (n,)


def gaussian_curvature(surface: AnalyticSurface) -> Curvature:
    """The Gaussian curvature of an analytic surface at its points (n, 3) -> (n,), in
    closed form: ``1 / r^2`` on a sphere (seen from either side), for the paraboloid
    ``z = z0 - k (x^2 + y^2)`` of :class:`Bowl` the graph formula
    ``(f_xx f_yy - f_xy^2) / (1 + |grad f|^2)^2 = 4 k^2 / (1 + 4 k^2 (x^2 + y^2))^2``,
    zero on a developable surface (away from its creases). A surface with another
    closed form (a saddle) passes its own to :func:`curvature_bound`."""
    if isinstance(surface, Sphere):
        r2 = surface.r**2
        return lambda p: np.full(p.shape[0], 1.0 / r2)
    if isinstance(surface, Bowl):
        return paraboloid_curvature(surface.k, 1.0)
    if surface.developable:
        return lambda p: np.zeros(p.shape[0])
    raise ValueError(f"no closed-form Gaussian curvature for the surface {surface.name!r}")


def paraboloid_curvature(k: float, sign: float) -> Curvature:
    """The Gaussian curvature of ``z = z0 - k (x^2 + sign y^2)``: sign 1 a bowl, -1 a
    saddle (``sign 4 k^2 / (1 + 4 k^2 (x^2 + y^2))^2``, the graph formula)."""
    return lambda p: sign * 4 * k * k / (1 + 4 * k * k * (p[:, 0] ** 2 + p[:, 1] ** 2)) ** 2


def least_spread(
    z: NDArray[np.complex128],
    charge: FloatArray,
    radius: FloatArray,
    degree: int = 8,
) -> float:
    """The least std of ``u_p + h`` (h harmonic) at chart points ``z`` (n,), where
    ``u_p`` is the logarithmic potential of the point charges ``charge`` (n,) (each a
    surface triangle's ``K dA``) at the same points, every point weighted alike (the
    harmonic fit: ``tests.warp.bound.harmonic_residual``).

    A charge's own potential at its centre is that of a uniform disc of ``radius``
    (n,) (its chart area's), ``-(q / 2 pi) (log radius - 1/2)``, not infinite."""
    u = np.empty(z.size)
    for s in range(0, z.size, 1024):  # (chunk, n) at a time
        d = np.abs(z[s : s + 1024, None] - z[None, :])
        idx = np.arange(s, min(s + 1024, z.size))
        d[idx - s, idx] = radius[idx] * np.exp(-0.5)
        u[s : s + 1024] = -(np.log(d) @ charge) / (2 * np.pi)
    return harmonic_residual(z, u, degree)


def curvature_bound(
    map_xy: NDArray[np.floating],
    surface: AnalyticSurface,
    K: FloatArray,
    mask: NDArray[np.floating],
    step: int = 16,
    curvature: Curvature | None = None,
    degree: int = 8,
) -> float:
    """The least size inconsistency (std of log size) of any angle-preserving map of the
    footprint that the displayed map ``map_xy`` (H, W, 2; content pixels per projector
    pixel, NaN where nothing shows) gives the subject ``mask`` (content-sized, >= 0.5
    inside), from the curvature of ``surface`` (its own closed form unless
    ``curvature`` is given) cast with the projector intrinsics ``K`` at every ``step``-th
    pixel (the cost grows as ``step^-4``; on the quality tests' large subjects 8, 12 and
    16 give ratios within 0.7 % of each other). The derivation is the module's."""
    kappa = curvature or gaussian_curvature(surface)
    h, w = map_xy.shape[:2]
    gx, gy = np.meshgrid(np.arange(0, w, step), np.arange(0, h, step))
    uv = np.stack([gx, gy], axis=-1).astype(np.float64)
    x = surface_points(surface, K, uv)
    c = map_xy[gy, gx].astype(np.float64)
    label = surface.patch(np.where(np.isfinite(x), x, 0.0))
    zs, qs, rs = [], [], []
    corners = (((0, 0), (0, 1), (1, 1)), ((0, 0), (1, 1), (1, 0)))
    r, k = gx.shape
    for tri in corners:
        sl = [(slice(a, a + r - 1), slice(b, b + k - 1)) for a, b in tri]
        p = [x[s].reshape(-1, 3) for s in sl]
        q = [c[s].reshape(-1, 2) for s in sl]
        lab = [label[s].ravel() for s in sl]
        ok = np.ones(p[0].shape[0], dtype=bool)
        for i in range(3):
            ok &= np.isfinite(p[i]).all(1) & np.isfinite(q[i]).all(1)
        ok &= (lab[0] == lab[1]) & (lab[1] == lab[2])
        e1, e2 = q[1] - q[0], q[2] - q[0]
        det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
        ok &= det > 0
        cent = (q[0] + q[1] + q[2])[ok] / 3
        mh, mw = mask.shape
        mx = np.clip(np.rint(cent[:, 0]).astype(int), 0, mw - 1)
        my = np.clip(np.rint(cent[:, 1]).astype(int), 0, mh - 1)
        inside = mask[my, mx] >= 0.5
        p0, p1, p2 = (pi[ok][inside] for pi in p)
        area = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
        qs.append(kappa((p0 + p1 + p2) / 3) * area)
        zs.append(cent[inside] @ np.array([1.0, 1j]))
        rs.append(np.sqrt(0.5 * det[ok][inside] / np.pi))
    return least_spread(np.concatenate(zs), np.concatenate(qs), np.concatenate(rs), degree)
