"""The smoothing of step 4: local quadratic fits of inverse depth over the lattice, in
side windows so that creases and steps stay sharp, at several scales."""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.depth.workspace import Workspace

_POWERS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))  # the quadratic basis x^a y^b
# the five windows (whole, left, right, up, down) as the half of the x and of the y axis
# each keeps: 0 = all offsets, 1 = offsets <= 0, 2 = offsets >= 0
_HALVES = ((0, 0), (1, 0), (2, 0), (0, 1), (0, 2))
_MOMENTS = tuple((a, b) for a in range(5) for b in range(5 - a))  # x^a y^b, a + b <= 4
_MOMENT_A, _MOMENT_B = np.array(_MOMENTS).T
_POWER_A, _POWER_B = np.array(_POWERS).T
# the x half of the whole, left, right windows; the y half of the up, down ones
_HX, _HY = np.arange(3), np.arange(2)
# entry (i, j) of the normal matrix: the moment of the product of basis functions i, j
_NORMAL = np.array([[_MOMENTS.index((a + c, b + d)) for c, d in _POWERS] for a, b in _POWERS])


def _axis_kernels(r: int, sigma: float) -> FloatArray:
    """(3 halves, 5 powers, 2r + 1): Gaussian x indicator of the half x (d / r)^p."""
    d = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-(d * d) / (2 * sigma**2))
    t = d / r
    half = np.stack([np.ones_like(d), d <= 0, d >= 0])
    return np.stack([g * half * t**p for p in range(5)], axis=1)


def _window_sums(a: FloatArray, kernels: FloatArray, step: int) -> FloatArray:
    """Correlation along axis 0 at every ``step``-th position, zeros outside.

    ``out[k, i, f] = sum_d kernels[k, d + r] * a[i * step + d, f]`` for ``a`` (n, f) and
    ``kernels`` (nk, 2r + 1); returns (nk, ceil(n / step), f). As a banded matrix product
    when the window is not much narrower than the axis, else over strided windows.
    """
    n, f = a.shape
    nk, width = kernels.shape
    r = width // 2
    m = (n - 1) // step + 1
    if n <= 4 * width:
        band = np.zeros((nk, m, n + 2 * r))
        s0, s1, s2 = band.strides  # row i of the band holds the kernel from column i * step
        diag = np.lib.stride_tricks.as_strided(band, (nk, m, width), (s0, s1 + step * s2, s2))
        diag[...] = kernels[:, None, :]
        return (band[:, :, r : r + n].reshape(nk * m, n) @ a).reshape(nk, m, f)
    padded = np.zeros((n + 2 * r, f))
    padded[r : r + n] = a
    win = np.lib.stride_tricks.sliding_window_view(padded, width, axis=0)[::step]
    out = np.ascontiguousarray(win).reshape(m * f, width) @ kernels.T
    return np.ascontiguousarray(out.reshape(m, f, nk).transpose(2, 0, 1))


def _window_moments(
    imgs: FloatArray, sigma: float, step: int, mom: FloatArray, bq: FloatArray, sqq: FloatArray
) -> FloatArray:
    """The weighted sums over the five windows of every kept node, for one scale.

    ``imgs`` (rows, cols, 3) holds m, m q and m q^2; written are ``mom`` (15, 5, ny, nx),
    the sums of m x^a y^b (:data:`_MOMENTS`), ``bq`` (6, 5, ny, nx), of m q x^a y^b
    (:data:`_POWERS`), and ``sqq`` (5, ny, nx), of m q^2; returns sum(w^2) / sum(w) of
    the weights of each window (5,). The weights are separable, so each sum is
    ``Ky @ img @ Kx.T`` with banded ``Kx``, ``Ky`` (:func:`_window_sums`).
    """
    rows, cols, _ = imgs.shape
    ny, nx = (rows - 1) // step + 1, (cols - 1) // step + 1
    r = int(np.ceil(2 * sigma))
    k1 = _axis_kernels(r, sigma)  # (half, power, offset)
    # along x, every (half, power) on the three images
    sx = _window_sums(imgs.transpose(1, 0, 2).reshape(cols, rows * 3), k1.reshape(15, -1), step)
    sx = sx.reshape(3, 5, nx, rows, 3).transpose(3, 4, 0, 1, 2)  # (rows, img, hx, a, nx)
    xm = sx[:, 0]  # m x^a
    xq = np.concatenate([sx[:, 1, :, :3], sx[:, 2, :, :1]], axis=2)  # m q x^0..2, m q^2
    # along y: the whole column with every x half; its upper, lower half with the whole x
    fm = _window_sums(xm.reshape(rows, -1), k1[0], step).reshape(5, ny, 3, 5, nx)
    fq = _window_sums(xq.reshape(rows, -1), k1[0, :3], step).reshape(3, ny, 3, 4, nx)
    um = _window_sums(xm[:, 0].reshape(rows, -1), k1[1:].reshape(10, -1), step)
    uq = _window_sums(xq[:, 0].reshape(rows, -1), k1[1:, :3].reshape(6, -1), step)
    um = um.reshape(2, 5, ny, 5, nx)
    uq = uq.reshape(2, 3, ny, 4, nx)
    hx, hy = _HX[None], _HY[None]
    a, b = _MOMENT_A[:, None], _MOMENT_B[:, None]
    mom[:, :3] = fm[b, :, hx, a]
    mom[:, 3:] = um[hy, b, :, a]
    a, b = _POWER_A[:, None], _POWER_B[:, None]
    bq[:, :3] = fq[b, :, hx, a]
    bq[:, 3:] = uq[hy, b, :, a]
    sqq[:3] = fq[0, :, _HX, 3]
    sqq[3:] = uq[_HY, 0, :, 3]
    # sum(w^2) / sum(w) of each window's weights w
    s1, s2 = np.sum(k1[:, 0], axis=1), np.sum(k1[:, 0] ** 2, axis=1)
    return np.array([s2[hx] * s2[hy] / (s1[hx] * s1[hy]) for hx, hy in _HALVES])


def _solve_spd(A: FloatArray, B: FloatArray) -> FloatArray:
    """Solve many small symmetric positive definite systems at once, overwriting the
    arguments: ``A`` (n, n, N) and ``B`` (n, c, N) hold N systems along the last axis;
    returns X (n, c, N) with ``A X = B``. Gaussian elimination without pivoting (stable
    for these matrices), each step one array operation over all systems.
    """
    n = A.shape[0]
    for k in range(n - 1):
        f = A[k + 1 :, k] / A[k, k]
        A[k + 1 :, k + 1 :] -= f[:, None] * A[k, None, k + 1 :]
        B[k + 1 :] -= f[:, None] * B[k, None]
    X = np.empty(B.shape)
    for k in range(n - 1, -1, -1):
        acc = B[k] - np.sum(A[k, k + 1 :, None] * X[k + 1 :], axis=0)
        X[k] = acc / A[k, k]
    return X


def _side_window_fits(
    s: FloatArray,
    sigmas: tuple[float, ...],
    min_weight: float = 3.0,
    switch: float = 3.0,
    step: int = 1,
    work: Workspace | None = None,
) -> tuple[FloatArray, FloatArray]:
    """:func:`side_window_fit` at several ``sigmas`` at once: (q, rss), each
    (len(sigmas), ceil(rows / step), ceil(cols / step))."""
    work = work if work is not None else Workspace()
    valid = np.isfinite(s) & (s > 0)
    q = np.where(valid, 1.0 / np.where(valid, s, 1.0), 0.0)
    m = valid.astype(np.float64)
    imgs = np.stack([m, m * q, m * q * q], axis=-1)
    valid = valid[::step, ::step]
    ns, (ny, nx) = len(sigmas), valid.shape
    shape = (ns, 5, ny, nx)  # scale, window, node
    mom = work.get("mom", (15, *shape))
    bq = work.get("bq", (6, *shape))
    sqq = work.get("sqq", shape)
    wbar = np.empty((ns, 5, 1, 1))  # sum(w^2) / sum(w) of the weights of each window
    for i, sigma in enumerate(sigmas):
        wbar[i, :, 0, 0] = _window_moments(imgs, sigma, step, mom[:, i], bq[:, i], sqq[i])
    w00 = mom[0]
    ok = valid & (w00 >= min_weight)
    bq[:, ~ok] = 0.0
    # the normal equations (A + 1e-9 I) c = b of every scale, window and node (A = I
    # where there is no fit), eliminated last variable first: the last pivot is then
    # 1 / (A^-1)_00
    n = ok.size
    A = np.take(mom.reshape(15, n), _NORMAL, axis=0, out=work.get("A", (6, 6, n)), mode="clip")
    A[:, :, ~ok.reshape(-1)] = np.eye(6)[:, :, None]
    A[np.arange(6), np.arange(6)] += 1e-9
    B = work.get("B", (6, 1, n))
    B[:, 0] = bq.reshape(6, n)[::-1]
    coef = _solve_spd(A[::-1, ::-1], B)[::-1, 0].reshape(6, *shape)
    a00 = (1.0 / A[0, 0]).reshape(shape)
    # weighted residual sum of squares from the moments: S - 2 c.b + c^T A c (A without
    # the 1e-9; where there is no fit c = 0)
    cAc = np.zeros(shape)
    for i in range(6):
        Ac = np.sum(mom[_NORMAL[i]] * coef, axis=0)
        Ac *= coef[i]
        cAc += Ac
    res = sqq - 2 * np.sum(coef * bq, axis=0) + cAc
    with np.errstate(invalid="ignore", divide="ignore"):
        R = np.where(ok, np.maximum(res, 0.0) / w00, np.inf)  # (scale, window, ny, nx)
    var = R * a00 * wbar
    side = 1 + np.argmin(R[:, 1:], axis=1)
    best_side = np.take_along_axis(R[:, 1:], (side - 1)[:, None], axis=1)[:, 0]
    choice = np.where(R[:, 0] > switch * best_side, side, 0)
    choice = np.where(ok[:, 0], choice, np.where(ok.any(axis=1), np.argmax(ok, axis=1), -1))
    pick = np.maximum(choice, 0)[:, None]
    qf = np.take_along_axis(coef[0], pick, axis=1)[:, 0]
    vf = np.take_along_axis(var, pick, axis=1)[:, 0]
    good = valid & (choice >= 0) & (qf > 0)
    return np.where(good, qf, np.nan), np.where(good, vf, np.inf)


def side_window_fit(
    s: FloatArray,
    sigma_nodes: float,
    min_weight: float = 3.0,
    switch: float = 3.0,
    step: int = 1,
) -> tuple[FloatArray, FloatArray]:
    """Local quadratic regression of inverse depth over the lattice (rows, cols), in
    side windows so that creases and steps stay sharp.

    For each node a quadratic in the lattice coordinates is fitted to ``1 / s`` of its
    neighbours (Gaussian weights of ``sigma_nodes``) in five windows: the whole
    neighbourhood and its left, right, upper and lower halves. The whole window is
    used unless one half fits ``switch`` times better (the node is next to a crease,
    where only the half on its own side belongs to its face). Inverse depth is affine
    in image coordinates on a plane, so walls stay exact; quadrics (spheres,
    cylinders, bowls) are followed up to third-order terms.

    Only the nodes ``[::step, ::step]`` are fitted (the whole lattice is data).

    Returns
    -------
    q : (ceil(rows / step), ceil(cols / step)) fitted inverse depth, NaN where no fit
    rss : same shape, weighted mean squared residual of the chosen window
    """
    q, rss = _side_window_fits(s, (sigma_nodes,), min_weight, switch, step)
    return q[0], rss[0]


def smooth_lattice(
    s: FloatArray,
    sigma_nodes: float,
    scales: tuple[float, ...] = (1.0,),
    accept: float = 1.5,
    step: int = 1,
    work: Workspace | None = None,
    floor: float = 0.0,
) -> FloatArray:
    """Side-window quadratic smoothing (:func:`side_window_fit`) at ``sigma_nodes``
    times each of ``scales`` (increasing): a node takes the largest scale whose fit is
    still about as good (differs by at most ``accept`` times the narrower fit's standard
    error, plus ``floor``) as the scale below it, so flat and gently curved parts get
    the most smoothing and tighter shapes keep their detail. ``floor`` is the inverse
    depth a narrower fit may follow without it being shape: the sensor's step
    (:attr:`~adaproj_edge.geometry.depth.sensor.SensorModel.inverse_step`), so a wall's
    staircase is smoothed over, not followed. Unknown nodes stay unknown; nodes without
    a fit keep their value.

    Returns the nodes ``[::step, ::step]`` (each depends only on the fits there; the
    whole lattice is data).
    """
    if sigma_nodes < 0.5:
        return s if step == 1 else s[::step, ::step]
    valid = (np.isfinite(s) & (s > 0))[::step, ::step]
    qs, vs = _side_window_fits(s, tuple(sigma_nodes * k for k in scales), step=step, work=work)
    q, var = qs[0], vs[0]
    for q2, var2 in zip(qs[1:], vs[1:], strict=True):
        with np.errstate(invalid="ignore"):
            take = np.isfinite(q2) & (np.abs(q2 - q) <= accept * np.sqrt(var) + floor)
        q = np.where(take, q2, q)
        var = np.where(take, var2, var)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(
            valid & np.isfinite(q) & (q > 0), 1.0 / q, np.where(valid, s[::step, ::step], np.nan)
        )
