"""Decoded camera pixels + the depth frame -> 3D points in frame D, each with the
projector pixel that lights it.

The camera is the one depth is aligned to (frame D), so a camera pixel's depth is
read from the depth image at the same place. Single pixels are poor pairs: each
decodes to a whole cell of projector pixels and its depth carries the stereo noise.
So pairs are made from square *patches* of camera pixels (``patch`` wide, every
``stride`` pixels): over a patch the projector coordinates and the inverse depth
are fitted as affine functions of the camera pixel (exact for inverse depth on a
plane, and to well under a pixel for the projector map over a few centimetres), a
few rounds dropping pixels far from the fit (decode errors); the pair is the fit
at the patch centre. A patch is refused where its fits do not hold — a depth edge,
the crease of a corner, light reflected from another wall scrambling the code — or
where too few of its pixels decoded. Each pair keeps the spread of its fits, from
which the solver weighs it.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray, IntArray
from adaproj_edge.procam.graycode import Decoded


@dataclass(frozen=True)
class PairSettings:
    """Patch size and acceptance limits (camera pixels; fit RMS in cells)."""

    patch: int = 12
    stride: int = 6
    min_fill: float = 0.6
    min_edges: int = 12
    min_spread: float = 2.0
    max_edge_rms: float = 0.5
    max_depth_rms_rel: float = 3.0
    reject: float = 3.0
    rounds: int = 2


@dataclass(frozen=True)
class Pairs:
    """Point pairs of one or more poses.

    Attributes
    ----------
    camera_uv : (n, 2) float
        Patch centres in camera pixels.
    points : (n, 3) float
        The 3D points in frame D, metres.
    projector_uv : (n, 2) float
        The projector pixels that light them.
    sigma_uv : (n,) float
        Standard error of ``projector_uv`` from its fit, projector pixels.
    sigma_z : (n,) float
        Standard error of the point's depth from its fit, metres.
    pose : (n,) int
        The pose each pair comes from.
    """

    camera_uv: FloatArray
    points: FloatArray
    projector_uv: FloatArray
    sigma_uv: FloatArray
    sigma_z: FloatArray
    pose: IntArray

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @classmethod
    def empty(cls) -> Pairs:
        z = np.zeros((0,))
        return cls(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 2)), z, z, np.zeros(0, np.intp))

    @classmethod
    def concat(cls, parts: list[Pairs]) -> Pairs:
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in _FIELDS))

    def select(self, keep: BoolArray | IntArray) -> Pairs:
        return Pairs(*(getattr(self, f)[keep] for f in _FIELDS))


_FIELDS = ("camera_uv", "points", "projector_uv", "sigma_uv", "sigma_z", "pose")


def depth_at_camera(depth_m: FloatArray, size: tuple[int, int]) -> FloatArray:
    """The depth image (hd, wd) resampled to the camera's pixels ``size`` (w, h): the
    depth pixel whose area holds each camera pixel's centre (both images cover the
    same field of view; depth is aligned to this camera)."""
    w, h = size
    hd, wd = depth_m.shape
    iu = np.clip(np.floor((np.arange(w) + 0.5) * wd / w).astype(np.intp), 0, wd - 1)
    iv = np.clip(np.floor((np.arange(h) + 0.5) * hd / h).astype(np.intp), 0, hd - 1)
    out: FloatArray = depth_m[iv[:, None], iu[None, :]]
    return out


def _windows(a: NDArray[np.float64], p: int, s: int) -> NDArray[np.float64]:
    """(ny, nx, p * p) patches of ``a`` (h, w) every ``s`` pixels."""
    win = np.lib.stride_tricks.sliding_window_view(a, (p, p))[::s, ::s]
    return np.ascontiguousarray(win).reshape(win.shape[0], win.shape[1], p * p)


def _fit(
    values: FloatArray, mask: BoolArray, design: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Batched least squares of ``values`` (..., m) on ``design`` (m, k) where ``mask``;
    coefficients (..., k), residuals (..., m) and the RMS residual (...,)."""
    k = design.shape[1]
    w = mask.astype(np.float64)
    v = np.where(mask, values, 0.0)
    outer = (design[:, :, None] * design[:, None, :]).reshape(-1, k * k)  # (m, k * k)
    normal = (w @ outer).reshape(*w.shape[:-1], k, k) + np.eye(k) * 1e-9
    rhs = v @ design
    coef = np.linalg.solve(normal, rhs[..., None])[..., 0]
    res = values - coef @ design.T
    n = np.maximum(w.sum(axis=-1), 1.0)
    rms = np.sqrt(np.sum(np.where(mask, res * res, 0.0), axis=-1) / np.maximum(n - k, 1.0))
    return np.asarray(coef, np.float64), np.asarray(res, np.float64), rms


def edge_samples(
    code: NDArray[np.int32], cell: int, diff: NDArray[np.float32]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Points on the edges between neighbouring cells, to a fraction of a pixel.

    Where two neighbouring camera pixels (along a row or a column) decode to cells
    ``c`` and ``c + 1``, exactly one bit of their Gray codes differs; its pattern
    minus inverse changes sign between them, and the zero crossing (on the cubic
    through these two pixels and one more either side) is where the projector's edge
    ``x = (c + 1) * cell - 0.5`` is seen.

    Parameters
    ----------
    code : (h, w) int32
        Cells, -1 where none.
    cell : int
        Cell size in projector pixels.
    diff : (bits, h, w) float32
        Normalised pattern - inverse of each bit used, most significant first.

    Returns
    -------
    u, v, value : (m,) float
        Camera positions of the edge points and the projector coordinate there.
    """
    kept = diff.shape[0]
    gray = code ^ (code >> 1)
    us, vs, vals = [], [], []
    h, w = code.shape
    rows, cols = np.mgrid[0:h, 0:w]
    for axis in (1, 0):
        n = (w if axis == 1 else h) - 1
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(0, n), slice(1, n + 1)
        c0, c1 = code[tuple(a)], code[tuple(b)]
        ok = (c0 >= 0) & (c1 >= 0) & (np.abs(c1 - c0) == 1)
        flip = (gray[tuple(a)] ^ gray[tuple(b)])[ok]
        bit = kept - 1 - np.log2(np.maximum(flip, 1)).round().astype(np.intp)
        r, q = rows[tuple(a)][ok], cols[tuple(a)][ok]
        d0 = diff[bit, r, q]
        d1 = diff[bit, r + (axis == 0), q + (axis == 1)]
        cross = (d0 * d1 < 0) & (bit >= 0)
        bit, r, q, d0, d1 = bit[cross], r[cross], q[cross], d0[cross], d1[cross]
        t = _zero_crossing(diff, bit, r, q, d0, d1, axis)
        us.append(q + (t if axis == 1 else 0.0))
        vs.append(r + (t if axis == 0 else 0.0))
        vals.append(np.maximum(c0[ok], c1[ok])[cross] * float(cell) - 0.5)
    return np.concatenate(us), np.concatenate(vs), np.concatenate(vals)


def _zero_crossing(
    diff: NDArray[np.float32],
    bit: IntArray,
    r: IntArray,
    q: IntArray,
    d0: FloatArray,
    d1: FloatArray,
    axis: int,
) -> FloatArray:
    """Where (0..1, from the first pixel) the differences ``d0``, ``d1`` of two
    neighbouring pixels along ``axis`` cross zero: on the cubic through them and the
    pixels either side (a blurred stripe edge is curved between two samples; the
    straight line alone is biased by where the edge falls), else on the line."""
    t = d0 / (d0 - d1)
    dy, dx = int(axis == 0), int(axis == 1)
    n = diff.shape[1 + (axis == 1)]
    pos = q if axis == 1 else r
    inner = (pos >= 1) & (pos + 2 < n)
    if not inner.any():
        return t
    b, rr, qq = bit[inner], r[inner], q[inner]
    dm = diff[b, rr - dy, qq - dx].astype(np.float64)
    d2 = diff[b, rr + 2 * dy, qq + 2 * dx].astype(np.float64)
    a0, a1 = d0[inner].astype(np.float64), d1[inner].astype(np.float64)

    def cubic(x: FloatArray) -> FloatArray:  # Lagrange through x = -1, 0, 1, 2
        y: FloatArray = (
            -dm * x * (x - 1) * (x - 2) / 6
            + a0 * (x + 1) * (x - 1) * (x - 2) / 2
            - a1 * (x + 1) * x * (x - 2) / 2
            + d2 * (x + 1) * x * (x - 1) / 6
        )
        return y

    x = t[inner].astype(np.float64)
    for _ in range(4):  # Newton steps from the straight line's crossing
        slope = (cubic(x + 1e-3) - cubic(x - 1e-3)) / 2e-3
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.clip(x - cubic(x) / slope, 0.0, 1.0)
    good = np.isfinite(x) & (np.abs(cubic(x)) < 1e-3)
    out = t.astype(np.float64).copy()
    out[np.flatnonzero(inner)[good]] = x[good]
    return out


def _patch_fit(
    u: FloatArray,
    v: FloatArray,
    val: FloatArray,
    grid: tuple[int, int],
    p: int,
    st: int,
    reject: float,
    rounds: int,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Affine fits ``val ~ a + b du + c dv`` of scattered samples over every patch of
    the ``grid`` (ny, nx) of ``p``-pixel patches every ``st`` pixels (du, dv from the
    patch centre); value at the centre (ny, nx), RMS residual, count, and the spread
    of the samples (the smaller singular value of their positions, pixels)."""
    ny, nx = grid
    pid, du, dv, y = [], [], [], []
    reach = -(-p // st)
    for oy in range(reach):
        iy = np.floor((v + 0.5) / st).astype(np.intp) - oy
        iny = (iy >= 0) & (iy < ny) & (v >= iy * st - 0.5) & (v < iy * st + p - 0.5)
        for ox in range(reach):
            ix = np.floor((u + 0.5) / st).astype(np.intp) - ox
            ok = iny & (ix >= 0) & (ix < nx) & (u >= ix * st - 0.5) & (u < ix * st + p - 0.5)
            pid.append(iy[ok] * nx + ix[ok])
            du.append(u[ok] - (ix[ok] * st + (p - 1) / 2.0))
            dv.append(v[ok] - (iy[ok] * st + (p - 1) / 2.0))
            y.append(val[ok])
    ids, x1, x2, yy = (np.concatenate(t) for t in (pid, du, dv, y))
    n_p = ny * nx
    use = np.ones(len(ids), bool)
    coef = np.zeros((n_p, 3))
    rms = np.full(n_p, np.inf)
    count = np.zeros(n_p)
    spread = np.zeros(n_p)
    for r in range(rounds + 1):
        wgt = use.astype(np.float64)
        terms = (1.0, x1, x2)
        N = np.empty((n_p, 3, 3))
        B = np.empty((n_p, 3))
        for i in range(3):
            B[:, i] = np.bincount(ids, wgt * terms[i] * yy, n_p)
            for j in range(i, 3):
                N[:, i, j] = N[:, j, i] = np.bincount(ids, wgt * terms[i] * terms[j], n_p)
        count = N[:, 0, 0]
        good = count >= 6
        Ng = N[good] + np.eye(3) * 1e-9
        coef[good] = np.linalg.solve(Ng, B[good][..., None])[..., 0]
        res = yy - (coef[ids, 0] + coef[ids, 1] * x1 + coef[ids, 2] * x2)
        ss = np.bincount(ids, wgt * res * res, n_p)
        rms = np.where(good, np.sqrt(ss / np.maximum(count - 3, 1.0)), np.inf)
        if r < rounds:
            use = np.abs(res) <= reject * np.maximum(rms[ids], 1e-3)
    # spread of the sample positions: the smaller eigenvalue of their covariance
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.maximum(count, 1.0)
        mu = N[:, 0, 1:] / n[:, None]
        cov = N[:, 1:, 1:] / n[:, None, None] - mu[:, :, None] * mu[:, None, :]
    spread = np.sqrt(np.maximum(np.linalg.eigvalsh(cov)[:, 0], 0.0))
    return (
        coef[:, 0].reshape(grid),
        rms.reshape(grid),
        count.reshape(grid),
        spread.reshape(grid),
    )


def pose_pairs(
    decoded: Decoded,
    depth_m: FloatArray,
    K_camera: FloatArray,
    pose: int = 0,
    settings: PairSettings | None = None,
) -> Pairs:
    """The pairs of one pose.

    Parameters
    ----------
    decoded : Decoded
        The pose's captures decoded (camera size (h, w)).
    depth_m : (hd, wd) float
        Depth in metres aligned to the camera, NaN where invalid (any resolution of
        the same field of view).
    K_camera : (3, 3) float
        The camera's intrinsics at (w, h).
    pose : int
        Index stored with the pairs.
    settings : PairSettings, optional
    """
    s = settings or PairSettings()
    h, w = decoded.code_x.shape
    p, st = s.patch, s.stride
    if h < p or w < p:
        return Pairs.empty()
    grid = ((h - p) // st + 1, (w - p) // st + 1)
    fits = []
    for code, cell, diff in (
        (decoded.code_x, decoded.cell_x, decoded.diff_x),
        (decoded.code_y, decoded.cell_y, decoded.diff_y),
    ):
        u, v, val = edge_samples(code, cell, diff)
        fits.append(_patch_fit(u, v, val, grid, p, st, s.reject, s.rounds))
    (x0, qx, nx_, spx), (y0, qy, ny_, spy) = fits
    # inverse depth: affine over the patch's pixels (exact on a plane)
    z = depth_at_camera(np.asarray(depth_m, np.float64), (w, h))
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = np.where(np.isfinite(z) & (z > 0) & decoded.lit, 1.0 / z, np.nan)
    ws = _windows(inv, p, st)
    ok = np.isfinite(ws)
    d = np.arange(p) - (p - 1) / 2.0
    dv, du = np.meshgrid(d, d, indexing="ij")
    design = np.stack([np.ones(p * p), du.ravel(), dv.ravel()], axis=1)
    m = ok.copy()
    for _ in range(s.rounds):
        cw, rw, qw = _fit(np.nan_to_num(ws), m, design)
        m = ok & (np.abs(rw) <= s.reject * np.maximum(qw, 1e-12)[..., None])
    cw, rw, qw = _fit(np.nan_to_num(ws), m, design)
    n_w = m.sum(axis=-1)
    min_n = s.min_edges
    keep = (n_w >= s.min_fill * p * p) & (cw[..., 0] > 0)
    keep &= (nx_ >= min_n) & (ny_ >= min_n) & (spx >= s.min_spread) & (spy >= s.min_spread)
    keep &= (qx <= s.max_edge_rms * decoded.cell_x) & (qy <= s.max_edge_rms * decoded.cell_y)
    if not keep.any():
        return Pairs.empty()
    # inverse depth noise relative to depth: the typical patch sets the scale
    rel = qw / np.maximum(np.abs(cw[..., 0]), 1e-12)
    keep &= rel <= s.max_depth_rms_rel * float(np.median(rel[keep]))
    iy, ix = np.nonzero(keep)
    u0 = ix * st + (p - 1) / 2.0
    v0 = iy * st + (p - 1) / 2.0
    zc = 1.0 / cw[iy, ix, 0]
    rays = np.stack([u0, v0, np.ones_like(u0)], axis=1) @ np.linalg.inv(K_camera).T
    sig_uv = np.hypot(qx[iy, ix] / np.sqrt(nx_[iy, ix]), qy[iy, ix] / np.sqrt(ny_[iy, ix]))
    sig_z = qw[iy, ix] / np.sqrt(np.maximum(n_w[iy, ix], 1.0)) * zc * zc
    return Pairs(
        np.stack([u0, v0], axis=1),
        rays * zc[:, None],
        np.stack([x0[iy, ix], y0[iy, ix]], axis=1),
        sig_uv / np.sqrt(2.0),
        sig_z,
        np.full(len(u0), pose, np.intp),
    )
