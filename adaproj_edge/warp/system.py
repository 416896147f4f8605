"""Weighted linear least squares with a fixed sparsity pattern, solved as a banded system.

The warp energies are sums of squared linear residuals ``sqrt(w_r) (a_r . x - c_r)``.
Their rows keep the same unknowns from one iteration to the next; only the row
weights (from the content map), some coefficients (edge directions) and the constants
change. :class:`BandedLeastSquares` therefore works out once where every product
``a_ri a_rj`` lands in the normal matrix, stored as an upper band, and each solve is
a weighted ``bincount`` plus a banded Cholesky factorisation (LAPACK ``pbtrf``),
about ``n * band^2`` flops for ``n`` unknowns.

Unknowns may be fixed (gauge constraints): their columns move to the right-hand side.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.linalg.lapack
import scipy.sparse
import scipy.sparse.linalg
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import WarpError

SPARSE_ABOVE = 3e7  # nf * band^2 (banded Cholesky flops) above which sparse LU is used


@dataclass
class Rows:
    """A block of residual rows: ``cols`` (m, k) unknown indices (-1 = unused), ``vals``
    (m, k) coefficients and ``rhs`` (m,) constants."""

    cols: IntArray
    vals: FloatArray
    rhs: FloatArray

    @staticmethod
    def concat(blocks: list[Rows]) -> Rows:
        """The blocks' rows stacked, columns padded to the widest block (-1 cols, 0 vals)."""
        k = max(b.cols.shape[1] for b in blocks)

        def pad(a: NDArray[np.generic], fill: float) -> NDArray[np.generic]:
            out = np.full((a.shape[0], k), fill, dtype=a.dtype)
            out[:, : a.shape[1]] = a
            return out

        return Rows(
            np.concatenate([pad(b.cols, -1) for b in blocks]).astype(np.intp),
            np.concatenate([pad(b.vals, 0.0) for b in blocks]).astype(np.float64),
            np.concatenate([b.rhs for b in blocks]).astype(np.float64),
        )


class BandedLeastSquares:
    """Solve ``min_x sum_r w_r (a_r . x - c_r)^2`` for a fixed row pattern.

    Parameters
    ----------
    cols : (m, k) int array
        Unknown index of each coefficient of each row, -1 where unused.
    n : int
        Number of unknowns.
    fixed : (n,) bool array
        Unknowns held at given values (removed from the system).
    sparse : bool, optional
        Factor with a sparse LU (SuperLU, minimum-degree ordering) instead of the banded
        Cholesky; by default when the band is wide enough for that to win
        (``nf * band^2 > SPARSE_ABOVE``, about a 30x30 grid and finer).
    """

    def __init__(
        self, cols: IntArray, n: int, fixed: NDArray[np.bool_], sparse: bool | None = None
    ) -> None:
        self.n = n
        self.fixed = fixed
        free_index = np.full(n + 1, -1, dtype=np.intp)  # slot n catches the -1 padding
        free = np.flatnonzero(~fixed)
        free_index[free] = np.arange(free.size)
        self.nf = int(free.size)
        if self.nf == 0:
            raise WarpError("no free unknowns in the warp system")
        self.cols_or_n = np.where(cols >= 0, cols, n)
        fc = free_index[self.cols_or_n]  # (m, k) free index or -1
        # the coefficients of free unknowns: their places in (m, k) order, free indices
        self.free_at = np.flatnonzero(fc >= 0)
        self.free_fc = fc.reshape(-1)[self.free_at]
        k = cols.shape[1]
        ia, ib = _pairs(k)  # pairs (a, b), a <= b within a row
        # the pairs that land in the band (both free), in (row, pair) order: their
        # coefficients' places in the (m, k) values, their rows and band places (only
        # these are multiplied; the sums are added in the same order)
        # (in 32 bits while the pairs are many: half the memory to go through)
        wide = (self.nf + 1) * (self.nf + 1) >= 2**31
        fc32: NDArray[np.signedinteger[Any]] = fc if wide else fc.astype(np.int32)
        pi = fc32[:, ia].reshape(-1)
        pj = fc32[:, ib].reshape(-1)
        used = np.flatnonzero(np.minimum(pi, pj) >= 0)
        i, j = np.take(pi, used), np.take(pj, used)
        gap = np.abs(i - j)
        band = int(gap.max()) if used.size else 0
        self.band = band
        # upper band storage ab[band + lo - hi, hi]; off-diagonal pairs appear once per
        # (a, b) with a < b, which is the whole symmetric contribution for the upper part.
        self.dump = (band + 1) * self.nf
        np.maximum(i, j, out=i)  # hi
        gap -= band
        gap *= -self.nf
        gap += i
        self.used_flat = gap.astype(np.intp)
        # (an integer division and a subtraction: several times quicker than divmod)
        rows = used // ia.size
        pair = used - rows * ia.size
        base = rows * k
        self.used_a, self.used_b = base + np.take(ia, pair), base + np.take(ib, pair)
        self.used_rows = rows
        self.sparse = (self.nf * band * band > SPARSE_ABOVE) if sparse is None else sparse
        if self.sparse:
            self._sparse_pattern()

    def _sparse_pattern(self) -> None:
        """The symmetric CSC pattern of the normal matrix, and where each of its entries
        sits in the band storage."""
        nf, band = self.nf, self.band
        used = np.unique(self.used_flat)
        hi = used % nf
        lo = used // nf - band + hi
        off = lo != hi
        rows = np.concatenate([lo, hi[off]])
        cols = np.concatenate([hi, lo[off]])
        src = np.concatenate([used, used[off]])
        tag = np.arange(1, src.size + 1, dtype=np.float64)
        csc = scipy.sparse.csc_matrix((tag, (rows, cols)), shape=(nf, nf))
        self.csc = csc
        self.csc_src = src[np.rint(csc.data).astype(np.intp) - 1]

    def normal_band(self, vals: FloatArray, weights: FloatArray) -> FloatArray:
        """The upper band (band + 1, nf) of ``A^T W A`` (a fresh array)."""
        v = np.ravel(vals)
        prod = np.take(v, self.used_a) * np.take(v, self.used_b) * np.take(weights, self.used_rows)
        ab = np.bincount(self.used_flat, weights=prod, minlength=self.dump)
        # (bincount's sums are float64 already: no copy)
        out: FloatArray = np.asarray(ab, dtype=np.float64).reshape(self.band + 1, self.nf)
        return out

    def _solve_normal(self, ab: FloatArray, b: FloatArray) -> FloatArray:
        try:
            if self.sparse:
                self.csc.data = ab.ravel()[self.csc_src]
                # symmetric positive definite: keep the pivots on the diagonal
                lu = scipy.sparse.linalg.splu(
                    self.csc,
                    permc_spec="MMD_AT_PLUS_A",
                    diag_pivot_thresh=0.0,
                    options={"SymmetricMode": True},
                )
                return np.asarray(lu.solve(b), dtype=np.float64)
            # LAPACK's dpbtrf / dpbtrs, what scipy.linalg.cholesky_banded and
            # cho_solve_banded call, without their checks and wrapping; ``ab`` is the
            # fresh array of normal_band, factored in place
            cb, info = _DPBTRF(ab, lower=0, overwrite_ab=1)
            if info == 0:
                x, info = _DPBTRS(cb, b, lower=0)
                if info == 0:
                    return np.asarray(x, dtype=np.float64)
        except (np.linalg.LinAlgError, RuntimeError):
            pass
        raise WarpError("the warp system is singular (the mesh is disconnected?)")

    def rhs(
        self, vals: FloatArray, const: FloatArray, weights: FloatArray, x_fixed: FloatArray
    ) -> FloatArray:
        """``A^T W (c - A_fixed x_fixed)`` over the free unknowns."""
        xf = np.append(np.where(self.fixed, x_fixed, 0.0), 0.0)
        c = const - np.sum(vals * xf[self.cols_or_n], axis=1)
        contrib = vals * (weights * c)[:, None]
        out = np.bincount(self.free_fc, weights=np.take(contrib, self.free_at), minlength=self.nf)
        return np.asarray(out, dtype=np.float64)  # (float64 already: no copy)

    def solve(
        self, vals: FloatArray, const: FloatArray, weights: FloatArray, x_fixed: FloatArray
    ) -> FloatArray:
        """Minimiser x (n,), with fixed unknowns copied from ``x_fixed``."""
        xs = self._solve_normal(
            self.normal_band(vals, weights), self.rhs(vals, const, weights, x_fixed)
        )
        x = np.array(x_fixed, dtype=np.float64, copy=True)
        x[~self.fixed] = xs
        if not np.all(np.isfinite(x)):
            raise WarpError("the warp solve produced non-finite values")
        return x


# LAPACK's banded Cholesky of real symmetric matrices, called directly (as below)
_DPBTRF, _DPBTRS = scipy.linalg.lapack.get_lapack_funcs(("pbtrf", "pbtrs"), (np.zeros(1),))

# LAPACK's banded Cholesky of complex Hermitian matrices, called directly: what
# scipy.linalg.cholesky_banded and cho_solve_banded call, without their checks and
# wrapping (tens of microseconds a call; a warp factors three times and solves ten)
_ZPBTRF, _ZPBTRS = scipy.linalg.lapack.get_lapack_funcs(
    ("pbtrf", "pbtrs"), (np.zeros(1, dtype=np.complex128),)
)


@functools.lru_cache(maxsize=8)
def _pairs(k: int) -> tuple[IntArray, IntArray]:
    """The index pairs (a <= b) of ``k`` coefficients (``np.triu_indices``, kept)."""
    a, b = np.triu_indices(k)
    a.flags.writeable = False
    b.flags.writeable = False
    return a, b


class ComplexLeastSquares:
    """Solve ``min_z sum_r w_r |a_r . z - c_r|^2`` over complex unknowns, fixed row pattern.

    The conformal energy is complex-linear in ``z = x + i y`` (eq. 4: ``R90`` is a
    multiplication by ``-i``), and so are the edge and position terms of the
    content-aware step: with complex unknowns the system has half the unknowns and a
    band half as wide as the real one, and its Hermitian normal matrix is factored by
    LAPACK's banded Cholesky (``zpbtrf``). The pattern is worked out once (memoised per
    topology); :meth:`factor` keeps the last factorisation, so steps with the same
    coefficients and weights cost one back-substitution each.

    Parameters
    ----------
    cols : (m, k) int array
        Unknown index of each coefficient of each row, -1 where unused.
    n : int
        Number of unknowns.
    fixed : (n,) bool array
        Unknowns held at given values (removed from the system).
    """

    def __init__(self, cols: IntArray, n: int, fixed: NDArray[np.bool_]) -> None:
        self.n = n
        self.fixed = fixed
        free_index = np.full(n + 1, -1, dtype=np.intp)
        self.free = free = np.flatnonzero(~fixed)
        free_index[free] = np.arange(free.size)
        self.nf = int(free.size)
        if self.nf == 0:
            raise WarpError("no free unknowns in the warp system")
        k = cols.shape[1]
        self.cols = np.where(cols >= 0, cols, n)  # slot n: unused (value 0, never fixed)
        fc = free_index[self.cols]
        # each coefficient of a free unknown: where it is in (m, k) order, its row, its
        # free index (in row order)
        self.entry_at = np.flatnonzero(fc >= 0)
        self.entry_rows = self.entry_at // k
        self.entry_free = fc.reshape(-1)[self.entry_at]
        # rows that see a fixed unknown (a used coefficient that has no free index)
        fixed_entry = np.flatnonzero((fc < 0) & (self.cols < n))
        fixed_rows = fixed_entry // k  # (sorted: its distinct values without a sort)
        self.fixed_rows = fixed_rows[np.diff(fixed_rows, prepend=-1) != 0]
        # the coefficient pairs of each row (a <= b) that land in the band (both free),
        # in (row, pair) order: where they are among the (m, pairs) products, their row
        # and their place in the band's storage (fancy indexing along the rows and
        # np.take of the kept ones: quicker than the reverse at these sizes)
        pair_a, pair_b = _pairs(k)
        i = fc[:, pair_a].reshape(-1)
        j = fc[:, pair_b].reshape(-1)
        used = np.flatnonzero(np.minimum(i, j) >= 0)
        i, j = np.take(i, used), np.take(j, used)
        lo, hi = np.minimum(i, j), np.maximum(i, j)
        gap = hi - lo
        self.band = band = int(gap.max()) if gap.size else 0
        self.dump = (band + 1) * self.nf
        self.used_flat = (band - gap) * self.nf + hi
        self.used = used  # flat indices of the (m, pairs) products
        self.used_rows = used // pair_a.size
        # a pair below the diagonal adds the conjugate of its product
        self.used_sign = np.where(i > j, -1.0, 1.0)
        # two coefficients of one unknown add twice the real part of their product
        # (only in rows that name an unknown twice: usually none)
        self.used_twice = np.zeros(0, dtype=np.intp)
        off = pair_a != pair_b
        fa, fb = fc[:, pair_a[off]], fc[:, pair_b[off]]
        if np.any((fa == fb) & (fa >= 0)):
            pair = used - self.used_rows * pair_a.size
            self.used_twice = np.flatnonzero((i == j) & off[pair])
        self.pair_a, self.pair_b = pair_a, pair_b
        # the coupling of the free unknowns to the fixed ones: per coefficient pair of a
        # fixed-seeing row, where its product lands in the (nf, n_fixed) matrix
        self.fixed_list = np.flatnonzero(fixed)
        slot = np.full(n + 1, -1, dtype=np.intp)
        slot[self.fixed_list] = np.arange(self.fixed_list.size)
        fr = self.fixed_rows
        fs = slot[self.cols[fr]]  # (r, k): the fixed slot of each coefficient, or -1
        ri, ka, kb = np.nonzero((fc[fr][:, :, None] >= 0) & (fs[:, None, :] >= 0))
        self._c_row, self._c_free, self._c_fixed = fr[ri], ka, kb
        self._c_flat = fc[fr][ri, ka] * self.fixed_list.size + fs[ri, kb]
        self._vals: NDArray[np.complex128] | None = None
        self._weights: FloatArray | None = None
        self._chol: NDArray[np.complex128] | None = None
        self._prod: tuple[FloatArray, FloatArray] = (np.zeros(0), np.zeros(0))
        self._adjoint: NDArray[np.complex128] = np.zeros(0, dtype=np.complex128)
        self._adjoint_first = -1
        self._coupling: NDArray[np.complex128] = np.zeros((0, 0), dtype=np.complex128)
        self._first: dict[int, int] = {}  # the first entry of a solve, by its zero_rows

    def factor(self, vals: NDArray[np.complex128], weights: FloatArray) -> None:
        """Factor ``A^H W A`` for coefficients ``vals`` (m, k) and row weights ``weights``
        (m,); nothing to do when both are the ones last factored."""
        if self._vals is not vals:
            # the products of the coefficient pairs that land in the band
            prod = np.conj(np.take(vals, self.pair_a, axis=1))
            prod *= np.take(vals, self.pair_b, axis=1)
            prod = np.take(prod, self.used)
            re = np.ascontiguousarray(prod.real)
            im = prod.imag * self.used_sign  # conjugated where the pair is swapped
            if self.used_twice.size:
                re[self.used_twice] *= 2.0
                im[self.used_twice] = 0.0
            self._prod = (re, im)
            self._vals = vals
        elif self._weights is not None and np.array_equal(self._weights, weights):
            return
        w = np.take(weights, self.used_rows)
        size = self.dump
        ab = np.empty(size, dtype=np.complex128)
        ab.real = np.bincount(self.used_flat, self._prod[0] * w, size)
        ab.imag = np.bincount(self.used_flat, self._prod[1] * w, size)
        chol, info = _ZPBTRF(ab.reshape(self.band + 1, self.nf), lower=0, overwrite_ab=1)
        if info != 0:
            raise WarpError("the warp system is singular (the mesh is disconnected?)")
        self._chol = chol
        self._weights = np.array(weights, copy=True)
        self._adjoint_first = -1  # made at the first solve, for the rows it needs
        # (A_free^H W A_fixed): what the fixed unknowns' values take from the right side
        r = self._c_row
        terms = np.conj(vals[r, self._c_free]) * self._weights[r] * vals[r, self._c_fixed]
        size = self.nf * self.fixed_list.size
        self._coupling = (
            np.bincount(self._c_flat, terms.real, size)
            + 1j * np.bincount(self._c_flat, terms.imag, size)
        ).reshape(self.nf, self.fixed_list.size)

    def solve(
        self,
        const: NDArray[np.complex128],
        z_fixed: NDArray[np.complex128],
        zero_rows: int = 0,
    ) -> NDArray[np.complex128]:
        """Minimiser (n,) for the last factored coefficients and weights and the
        constants ``const`` (m,); the fixed unknowns are copied from ``z_fixed`` (n,).
        ``zero_rows``: the caller's word that ``const[:zero_rows]`` is zero (those rows
        then add nothing to the right side, and are not read)."""
        if self._chol is None or self._vals is None or self._weights is None:
            raise WarpError("the warp system has not been factored")
        # the entries are in row order: those of the first zero_rows rows come first
        first = self._first.get(zero_rows)
        if first is None:
            first = int(np.searchsorted(self.entry_rows, zero_rows)) if zero_rows else 0
            self._first[zero_rows] = first
        if not 0 <= self._adjoint_first <= first:
            # A^H W for the entries from ``first`` on (kept while later solves need no more)
            self._adjoint = np.conj(np.take(self._vals, self.entry_at[first:]))
            self._adjoint *= self._weights[self.entry_rows[first:]]
            self._adjoint_first = first
        rows = self.entry_rows[first:]
        contrib = self._adjoint[first - self._adjoint_first :] * const[rows]
        idx = self.entry_free[first:]
        rhs = np.empty(self.nf, dtype=np.complex128)
        rhs.real = np.bincount(idx, contrib.real, self.nf)
        rhs.imag = np.bincount(idx, contrib.imag, self.nf)
        if self.fixed_list.size:
            rhs -= self._coupling @ z_fixed[self.fixed_list]
        zs, info = _ZPBTRS(self._chol, rhs, lower=0, overwrite_b=1)
        if info != 0:
            raise WarpError("the warp solve failed")
        z = np.array(z_fixed, dtype=np.complex128, copy=True)
        z[self.free] = zs
        if not np.isfinite(z).all():
            raise WarpError("the warp solve produced non-finite values")
        return z
