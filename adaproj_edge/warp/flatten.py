"""Size flattening: a warp composed with the holomorphic map that evens out the smooth
part of its size over the subject, without adding angle error.

Any map of the content plane that is holomorphic (with non-zero derivative) keeps angles;
composed with a warp, it leaves the warp's angle error as it is and changes its log
size by ``-log|F'|``, a harmonic function. So the part of a warp's log size over the
subject that a low-degree harmonic function fits can be removed exactly: with the fit
``Re p(zeta)`` (``p`` a complex polynomial without constant, ``zeta`` the normalised
content position), ``F' = exp(p)`` and ``F(zeta) = integral of exp(p) from 0``, in
closed-form quadrature per vertex. On a large subject of a doubly curved surface, where
the alternation cannot even out size within the conformal warp's angle error, this
takes the warp toward the least size spread any angle-preserving warp has there
(docs/engine.md, "Large subjects"). Pure: no hardware, no clock.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.orientation import unfolded

DEGREE = 2  # the fit's degree (the least size spread no longer drops beyond 2)
# the largest ratio of F's scale over the mesh to its scale at the subject's centre
# (either way): beyond it the map would crowd or stretch the content off the subject
MAX_SCALE_LOG = 2.0
# Gauss-Legendre nodes and weights on [0, 1] for F(zeta) = zeta * int_0^1 exp(p(s zeta)) ds
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(16)
_NODES, _WEIGHTS = 0.5 * (_NODES + 1.0), 0.5 * _WEIGHTS


def harmonic_fit(
    z: NDArray[np.complex128], values: FloatArray, weight: FloatArray, degree: int = DEGREE
) -> tuple[complex, float, NDArray[np.complex128]] | None:
    """The weighted least-squares fit of ``values`` (T,) at complex points ``z`` (T,) by
    ``c + Re p((z - z0) / s)``, ``p`` a complex polynomial of ``degree`` without
    constant term: returns ``z0`` (the weighted centre), ``s`` (the largest weighted
    point's distance from it) and p's coefficients (degree,), lowest first; None when
    fewer points carry weight than the fit has unknowns."""
    keep = weight > 0
    if np.count_nonzero(keep) < 2 * degree + 2:
        return None
    zk, vk, wk = z[keep], values[keep], weight[keep]
    z0 = complex(np.sum(wk * zk) / np.sum(wk))
    s = float(np.max(np.abs(zk - z0)))
    if not s > 0:
        return None
    zeta = (zk - z0) / s
    cols = [np.ones(zk.size)]
    power = np.ones(zk.size, dtype=np.complex128)
    for _ in range(degree):
        power = power * zeta
        cols += [power.real, -power.imag]  # Re(a zeta^k) = a.re Re zeta^k - a.im Im zeta^k
    root = np.sqrt(wk)
    coef, *_ = np.linalg.lstsq(np.stack(cols, axis=1) * root[:, None], vk * root, rcond=None)
    if not np.all(np.isfinite(coef)):
        return None
    return z0, s, coef[1::2] + 1j * coef[2::2]


def flattened(
    mesh: MeshGeometry, v: FloatArray, log_size: FloatArray, weight: FloatArray
) -> FloatArray | None:
    """Positions ``v`` (n, 2) composed with the holomorphic map whose log scale cancels
    the harmonic fit of ``log_size`` (T,), the per-triangle log size of ``v`` (content ->
    surface), over the triangles of ``weight`` (T,) > 0; None when there is nothing to
    fit, the map would rescale the mesh more than ``exp(MAX_SCALE_LOG)`` anywhere, or
    the result folds.

    The map fixes the subject's weighted centre with unit derivative there, so the
    flattened warp stays where the warp was around the subject."""
    z = v[:, 0] + 1j * v[:, 1]
    centroids = np.take(z, mesh.tris.T).mean(axis=0)
    fit = harmonic_fit(centroids, log_size, weight)
    if fit is None:
        return None
    z0, s, a = fit
    zeta = (z - z0) / s

    def p(x: NDArray[np.complex128]) -> NDArray[np.complex128]:
        out: NDArray[np.complex128] = np.zeros_like(x)
        for c in a[::-1]:  # Horner, without the constant term
            out = (out + c) * x
        return out

    if float(np.max(np.abs(p(zeta).real))) > MAX_SCALE_LOG:
        return None
    f = zeta * (np.exp(p(zeta[:, None] * _NODES[None, :])) @ _WEIGHTS)
    out = z0 + s * f
    flat = np.stack([out.real, out.imag], axis=1)
    if not np.all(np.isfinite(flat)) or not unfolded(flat, mesh.tris):
        return None
    return flat
