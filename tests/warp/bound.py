"""How far any warp can even out a large subject's size without more angle error than the
conformal warp's: an optimisation independent of the engine (issue 13, "Large subjects").

The map content -> surface is scored at the scorer's sample points (every ``step``-th
projector pixel, rays cast at the analytic surface, ``tests/distortion.py``). The
unknowns are either the content positions of the conformal warp's grid vertices, shown
through the per-pixel display's own weights (``on_grid``: any warp the engine's grid can
show), or each sample's content position itself (any warp at all, of detail finer than
the grid's); two are pinned (the similarity is free), and

``E = sum_subject sqrt(angle^2 + EPS^2) + mu (A / V) (log size - m)^2``

is minimised (``scipy.optimize.least_squares``), where per sample triangle the Jacobian
content -> surface, written ``a z + b conj(z)`` in the triangle's plane, has angle error
``2|b| / (|a| - |b|)`` (the scorer's ``s1 / s2 - 1``) and log size
``log sqrt(|a|^2 - |b|^2)``, ``m`` is free, and ``A`` and ``V`` are the conformal warp's
mean angle error and log size variance there (``mu = 1`` weighs the two alike). The
start is the conformal warp as displayed; ``mu`` is swept. Each result is scored by the
same scorer as the quality tests (``tests.distortion.measure``), on the subject, against
the conformal warp at the same sampling. ``E``'s two sums are (up to ``EPS``, smoothing
the kink at zero) the total angle error and the size variance on the subject, so the
result at a ``mu`` where its angle error reaches the conformal warp's is, for a global
optimum, the least size spread of any warp with no more angle error; the local
optimiser and the subject taken at the conformal warp's centroids make this evidence,
not proof.

Separately, :func:`conformal_bound` gives the least size spread of any *exactly*
conformal map of the subject's piece of surface: the log scale of one conformal map
(the optimisation of the samples at ``mu = 0``) plus the harmonic function (harmonic
polynomials of the content position, degree <= 8) that evens it out best.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.sparse
from numpy.typing import NDArray

from adaproj_edge.geometry.analytic import get_surface
from adaproj_edge.render.maps import PixelWeights
from tests.distortion import in_mask, measure, surface_points
from tests.warp.conftest import subject_masks, surface, warped

FloatArray = NDArray[np.float64]
EPS = 1e-4  # smooths the angle error's kink at zero (typical values: 2e-3)


@dataclass(frozen=True)
class Point:
    """One warp scored on the subject: ``mu`` (None: the conformal warp), mean angle
    error, size inconsistency, and the folded sample triangles."""

    mu: float | None
    angle: float
    size: float
    folds: int


@dataclass
class Problem:
    """The sample lattice of one surface, the unknowns and the subject.

    The samples' content positions are ``basis @ v`` for the unknown positions ``v``
    (the samples themselves, or the grid vertices of the conformal warp through the
    display's own weights)."""

    name: str
    mask: str
    step: int
    gx: NDArray[np.intp]
    gy: NDArray[np.intp]
    basis: scipy.sparse.csr_matrix  # (N, V) samples from unknowns
    v0: FloatArray  # (V, 2) the conformal warp's unknowns
    frames: FloatArray  # (T, 2, 2) each triangle's edges in its own plane
    tris: NDArray[np.intp]  # (T, 3) indices into the kept samples
    subject: NDArray[np.bool_]  # (T,) triangles of the subject (conformal centroid)
    sample: NDArray[np.intp]  # (N,) flat index of each kept sample in the lattice
    map_shape: tuple[int, int]


def problem(name: str, mask: str, step: int = 8, on_grid: bool = False) -> Problem:
    """The optimisation problem for the subject ``mask`` on the surface ``name``: the
    unknowns are the samples (any warp), or ``on_grid`` the vertices of the conformal
    warp's grid, shown through the per-pixel display's weights (any warp of that grid)."""
    warp, m = warped(name, "conformal")
    h, w = m.shape[:2]
    ys, xs = np.arange(0, h, step), np.arange(0, w, step)
    gx, gy = np.meshgrid(xs, ys)
    uv = np.stack([gx, gy], axis=-1).astype(np.float64)
    x = surface_points(get_surface(name), surface(name).projector.K, uv)
    ok = np.isfinite(m[gy, gx]).all(axis=-1) & np.isfinite(x).all(axis=-1)
    if on_grid:
        pw = PixelWeights.build(warp.grid_uv, warp.depth, warp.projector, surface(name))
        corners = pw.corners[:, gy, gx].reshape(pw.corners.shape[0], -1)
        weights = pw.weights[:, gy, gx].reshape(pw.weights.shape[0], -1).astype(np.float64)
        ok &= np.isfinite(weights).all(axis=0).reshape(ok.shape)
    kept = np.flatnonzero(ok.ravel())
    if on_grid:
        verts = warp.image_xy.reshape(-1, 2)
        k = corners.shape[0]
        full = scipy.sparse.coo_matrix(
            (
                weights[:, kept].ravel(),
                (np.tile(np.arange(kept.size), k), corners[:, kept].ravel()),
            ),
            shape=(kept.size, verts.shape[0]),
        ).tocsc()
        used = np.flatnonzero(np.asarray((full != 0).sum(axis=0)).ravel() > 0)
        basis = full[:, used].tocsr()
        v0 = verts[used]
    else:
        basis = scipy.sparse.identity(kept.size, format="csr")
        v0 = m[gy, gx].astype(np.float64).reshape(-1, 2)[kept]
    r, k = gx.shape
    idx = np.arange(r * k).reshape(r, k)
    tris = []
    for a, b, d in (((0, 0), (0, 1), (1, 1)), ((0, 0), (1, 1), (1, 0))):
        tris.append(
            np.stack(
                [idx[o0 : o0 + r - 1, o1 : o1 + k - 1].ravel() for o0, o1 in (a, b, d)], axis=1
            )
        )
    t = np.concatenate(tris)
    t = t[ok.ravel()[t].all(axis=1)]
    compact = np.full(r * k, -1)
    compact[kept] = np.arange(kept.size)
    p = x.reshape(-1, 3)
    e1, e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    ex = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    n = np.cross(e1, e2)
    ey = np.cross(n / np.linalg.norm(n, axis=1, keepdims=True), ex)
    frames = np.stack(
        [
            np.stack([np.sum(e1 * ex, 1), np.sum(e2 * ex, 1)], 1),
            np.stack([np.sum(e1 * ey, 1), np.sum(e2 * ey, 1)], 1),
        ],
        axis=1,
    )  # rows: frame axes, columns: edges
    tris_c = compact[t]
    cent = (basis @ v0)[tris_c].mean(axis=1)
    msk = subject_masks()[mask]
    mh, mw = msk.shape
    sx = np.clip(np.rint(cent[:, 0]).astype(int), 0, mw - 1)
    sy = np.clip(np.rint(cent[:, 1]).astype(int), 0, mh - 1)
    return Problem(
        name, mask, step, gx, gy, basis, v0, frames, tris_c, msk[sy, sx] >= 0.5, kept, (h, w)
    )


def jacobians(pb: Problem, c: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Complex ``a`` and ``b`` (T,) of each triangle's Jacobian content -> surface for
    sample content positions ``c`` (N, 2)."""
    q = c[pb.tris]
    dq = np.stack([q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]], axis=2)  # columns: edges
    det = dq[:, 0, 0] * dq[:, 1, 1] - dq[:, 0, 1] * dq[:, 1, 0]
    inv = (
        np.stack(
            [
                np.stack([dq[:, 1, 1], -dq[:, 0, 1]], axis=1),
                np.stack([-dq[:, 1, 0], dq[:, 0, 0]], axis=1),
            ],
            axis=1,
        )
        / det[:, None, None]
    )
    j = pb.frames @ inv
    return _ab(j[:, 0, 0], j[:, 0, 1], j[:, 1, 0], j[:, 1, 1])


def optimise(pb: Problem, mu: float, start: FloatArray | None = None) -> FloatArray:
    """Unknowns (V, 2) minimising ``E`` for ``mu`` from ``start`` (default: the
    conformal warp's). Only the subject's triangles count: elsewhere the warp may do
    anything (the engine's background absorbs what the subject refuses), so only the
    unknowns that move them are free."""
    v_start = pb.v0 if start is None else start
    subj = np.flatnonzero(pb.subject)
    tris, frames = pb.tris[subj], pb.frames[subj]
    t_count = subj.size
    incidence = scipy.sparse.coo_matrix(
        (np.ones(3 * t_count), (np.repeat(np.arange(t_count), 3), tris.ravel())),
        shape=(t_count, pb.basis.shape[0]),
    ).tocsr()
    touched = np.asarray(abs(incidence @ pb.basis).sum(axis=0)).ravel() > 0
    # two pinned (the similarity is free): those with most weight on the subject's
    # first and last sample
    ends = np.unique(tris)[[0, -1]]
    heavy = np.asarray(abs(pb.basis[ends]).argmax(axis=1)).ravel()
    free = touched.copy()
    free[heavy] = False
    nf = int(free.sum())
    b_free = pb.basis[:, free]
    fixed = pb.basis[:, ~free] @ v_start[~free]
    sub = Problem(**{**pb.__dict__, "tris": tris, "frames": frames})
    a0, b0 = jacobians(sub, pb.basis @ pb.v0)
    angle0 = float(np.mean(2 * np.abs(b0) / (np.abs(a0) - np.abs(b0))))
    var0 = float(np.var(np.log(np.abs(a0)))) + 1e-30
    m0 = float(np.mean(np.log(np.abs(jacobians(sub, pb.basis @ v_start)[0]))))
    # both terms relative to the conformal warp's: mu = 1 weighs them alike
    sq = np.sqrt(mu * angle0 / var0)

    def residuals(x: FloatArray) -> FloatArray:
        return _residuals(sub, b_free, fixed, sq, x)[0]

    def jacobian(x: FloatArray) -> scipy.sparse.csr_matrix:
        return _residuals(sub, b_free, fixed, sq, x, jacobian=True)[1]

    x0 = np.concatenate([v_start[free].ravel(), [m0]])
    res = scipy.optimize.least_squares(
        residuals,
        x0,
        jac=jacobian,
        method="trf",
        tr_solver="lsmr",
        x_scale="jac",
        xtol=1e-10,
        ftol=1e-10,
        max_nfev=200,
    )
    out = v_start.copy()
    out[free] = res.x[: 2 * nf].reshape(-1, 2)
    return out


def _residuals(
    sub: Problem,
    b_free: scipy.sparse.csr_matrix,
    fixed: FloatArray,
    sq: float,
    x: FloatArray,
    jacobian: bool = False,
) -> tuple[FloatArray, scipy.sparse.csr_matrix | None]:
    """``E``'s residuals (2 T,) on the subject's triangles ``sub.tris`` for the unknowns
    ``x`` (the nf free positions, then ``m``), and (``jacobian``) their derivatives
    (2 T, 2 nf + 1): an analytic Jacobian, ~20x cheaper than finite differences.

    The derivatives are exact (a check against finite differences:
    ``tests/warp/test_large_bound.py``): with ``j = F inv(dq)`` (``F`` the triangle's
    edges in its plane, ``dq`` its content edges), moving sample ``k`` of the triangle
    by ``e_d`` changes ``dq`` by ``e_d g_k^T`` (``g``: (-1, -1), (1, 0), (0, 1)), so
    ``dj = -j e_d g_k^T inv(dq)``; ``a`` and ``b`` are linear in ``j``."""
    nf = b_free.shape[1]
    c = b_free @ x[: 2 * nf].reshape(-1, 2) + fixed
    q = c[sub.tris]  # (T, 3, 2)
    e1, e2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    # inv(dq), dq's columns the edges e1, e2: rows (e2y, -e2x) and (-e1y, e1x) over det
    i00, i01, i10, i11 = e2[:, 1] / det, -e2[:, 0] / det, -e1[:, 1] / det, e1[:, 0] / det
    f = sub.frames
    j00 = f[:, 0, 0] * i00 + f[:, 0, 1] * i10
    j01 = f[:, 0, 0] * i01 + f[:, 0, 1] * i11
    j10 = f[:, 1, 0] * i00 + f[:, 1, 1] * i10
    j11 = f[:, 1, 0] * i01 + f[:, 1, 1] * i11

    a, b = _ab(j00, j01, j10, j11)
    ab_, bb = np.abs(a), np.abs(b)
    gap = np.maximum(ab_ - bb, 1e-300)
    raw = 2 * bb / gap
    angle = np.minimum(raw, 1e3)
    area = np.maximum(ab_**2 - bb**2, 1e-300)
    size = 0.5 * np.log(area) - x[-1]
    root = angle**2 + EPS**2
    values = np.concatenate([root**0.25, sq * size])
    if not jacobian:
        return values, None
    # d residual / d |a|, d |b| (zero where a guard above is in force)
    live = (raw < 1e3) & (ab_ - bb > 1e-300)
    d_angle = np.where(live, 0.5 * angle * root**-0.75, 0.0)  # d res / d angle
    ra = d_angle * (-2 * bb / gap**2)
    rb = d_angle * (2 * ab_ / gap**2)
    on = ab_**2 - bb**2 > 1e-300
    sa = np.where(on, sq * ab_ / area, 0.0)
    sb = np.where(on, -sq * bb / area, 0.0)
    ua = np.conj(a) / np.maximum(ab_, 1e-300)  # d|a| = Re(ua da)
    ub = np.conj(b) / np.maximum(bb, 1e-300)
    t_count = det.size
    rows = np.arange(t_count)
    per_coord = []
    for d in range(2):
        parts = []
        for k, (g1, g2) in enumerate(((-1.0, -1.0), (1.0, 0.0), (0.0, 1.0))):
            h0 = g1 * i00 + g2 * i10  # g_k^T inv(dq)
            h1 = g1 * i01 + g2 * i11
            col0, col1 = (j00, j10) if d == 0 else (j01, j11)  # j e_d
            da, db = _ab(-col0 * h0, -col0 * h1, -col1 * h0, -col1 * h1)
            dabs_a, dabs_b = np.real(ua * da), np.real(ub * db)
            dres = np.concatenate([ra * dabs_a + rb * dabs_b, sa * dabs_a + sb * dabs_b])
            parts.append((dres, sub.tris[:, k]))
        data = np.concatenate([p for p, _ in parts])
        cols = np.concatenate([np.concatenate([idx, idx]) for _, idx in parts])
        row = np.tile(np.concatenate([rows, t_count + rows]), 3)
        samples = scipy.sparse.coo_matrix(
            (data, (row, cols)), shape=(2 * t_count, b_free.shape[0])
        ).tocsr()
        per_coord.append(samples @ b_free)  # (2 T, nf)
    # columns x0, y0, x1, y1, ..., then m
    stacked = scipy.sparse.hstack([per_coord[0], per_coord[1]]).tocsc()
    order = np.arange(2 * nf).reshape(2, nf).T.ravel()
    dm = scipy.sparse.csc_matrix(
        (np.full(t_count, -sq), (t_count + rows, np.zeros(t_count, dtype=np.intp))),
        shape=(2 * t_count, 1),
    )
    return values, scipy.sparse.hstack([stacked[:, order], dm]).tocsr()


def _ab(
    p_: FloatArray, q_: FloatArray, r_: FloatArray, s_: FloatArray
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Complex ``a``, ``b`` of the 2x2 ``[[p, q], [r, s]]`` written ``a z + b conj(z)``."""
    return 0.5 * ((p_ + s_) + 1j * (r_ - q_)), 0.5 * ((p_ - s_) + 1j * (r_ + q_))


def score(pb: Problem, v: FloatArray, mu: float | None) -> Point:
    """The scorer's figures on the subject for unknowns ``v`` (V, 2)."""
    c = pb.basis @ v
    full = np.full((*pb.map_shape, 2), np.nan, dtype=np.float32)
    flat = np.full((pb.gx.size, 2), np.nan)
    flat[pb.sample] = c
    full[pb.gy, pb.gx] = flat.reshape(*pb.gx.shape, 2)
    d = measure(full, get_surface(pb.name), surface(pb.name).projector.K, pb.step)
    s = d.select(in_mask(d, subject_masks()[pb.mask]))
    return Point(mu, s.angle_mean, s.size_std, d.folds)


def harmonic_residual(z: NDArray[np.complex128], values: FloatArray, degree: int = 8) -> float:
    """The spread (std) of ``values`` at complex points ``z`` left after the best fit by a
    harmonic function of z (``Re z^k``, ``Im z^k`` up to ``degree``, and a constant).

    With ``values`` the log size of a conformal map at its content positions ``z``, this
    is the least size spread of any exactly conformal map of the same piece of surface:
    every other one is f(z) with f holomorphic, whose log size differs by the harmonic
    ``log|f'(z)|``."""
    z = (z - z.mean()) / np.abs(z - z.mean()).max()
    basis = [np.ones(z.size)]
    for k in range(1, degree + 1):
        basis += [(z**k).real, (z**k).imag]
    b = np.stack(basis, axis=1)
    coef, *_ = np.linalg.lstsq(b, values, rcond=None)
    return float(np.std(values - b @ coef))


def conformal_bound(pb: Problem, v_conformal: FloatArray, degree: int = 8) -> float:
    """The least size spread on the subject of any exactly conformal map: the log scale of
    the conformal map of unknowns ``v_conformal`` (V, 2) plus the best harmonic function
    of the content position (:func:`harmonic_residual`)."""
    c_conformal = pb.basis @ v_conformal
    a, _ = jacobians(pb, c_conformal)
    ls = np.log(np.abs(a))[pb.subject]
    z = c_conformal[pb.tris[pb.subject]].mean(axis=1) @ np.array([1.0, 1j])
    return harmonic_residual(z, ls, degree)


def sweep(
    name: str, mask: str, mus: tuple[float, ...], step: int = 8, on_grid: bool = True
) -> tuple[Problem, Point, list[tuple[Point, FloatArray]]]:
    """The problem, the conformal warp's figures and, for ``mu = 0`` and then each of
    ``mus`` (each started from the last), the optimised warp's figures and unknowns."""
    pb = problem(name, mask, step, on_grid)
    conf = score(pb, pb.v0, None)
    out = []
    last = pb.v0
    for mu in (0.0, *mus):
        last = optimise(pb, mu, last)
        out.append((score(pb, last, mu), last))
    return pb, conf, out


def best_within(conf: Point, points: list[Point]) -> float:
    """The least size spread, as a ratio to the conformal warp's, of the fold-free
    points whose angle error is no more than the conformal warp's."""
    ok = [p.size for p in points if p.folds == 0 and p.angle <= conf.angle]
    return min(ok) / conf.size if ok else float("inf")
