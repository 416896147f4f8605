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

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.projector import FloatArray

IntArray = NDArray[np.intp]


@dataclass
class Rows:
    """A block of residual rows: ``cols`` (m, k) unknown indices (-1 = unused), ``vals``
    (m, k) coefficients and ``rhs`` (m,) constants."""

    cols: IntArray
    vals: FloatArray
    rhs: FloatArray

    @staticmethod
    def concat(blocks: list[Rows]) -> Rows:
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
    """

    def __init__(self, cols: IntArray, n: int, fixed: NDArray[np.bool_]) -> None:
        self.cols = cols
        self.n = n
        self.fixed = fixed
        free_index = np.full(n + 1, -1, dtype=np.intp)  # slot n catches the -1 padding
        free = np.flatnonzero(~fixed)
        free_index[free] = np.arange(free.size)
        self.nf = int(free.size)
        if self.nf == 0:
            raise WarpError("no free unknowns in the warp system")
        fc = free_index[np.where(cols >= 0, cols, n)]  # (m, k) free index or -1
        self.fc = fc
        m, k = cols.shape
        ia, ib = np.triu_indices(k)  # pairs (a, b), a <= b within a row
        self.pair_a = ia
        self.pair_b = ib
        i = fc[:, ia]
        j = fc[:, ib]
        ok = (i >= 0) & (j >= 0)
        lo = np.minimum(i, j)
        hi = np.maximum(i, j)
        band = int(np.max(np.where(ok, hi - lo, 0))) if ok.any() else 0
        self.band = band
        # upper band storage ab[band + lo - hi, hi]; off-diagonal pairs appear once per
        # (a, b) with a < b, which is the whole symmetric contribution for the upper part.
        flat = (band + lo - hi) * self.nf + hi
        self.dump = (band + 1) * self.nf
        self.flat = np.where(ok, flat, self.dump).ravel()
        self.row_of_pair = np.repeat(np.arange(m), ia.size)

    def normal_band(self, vals: FloatArray, weights: FloatArray) -> FloatArray:
        """The upper band (band + 1, nf) of ``A^T W A``."""
        prod = vals[:, self.pair_a] * vals[:, self.pair_b] * weights[:, None]
        ab = np.bincount(self.flat, weights=prod.ravel(), minlength=self.dump + 1)
        out: FloatArray = ab[: self.dump].reshape(self.band + 1, self.nf).astype(np.float64)
        return out

    def rhs(
        self, vals: FloatArray, const: FloatArray, weights: FloatArray, x_fixed: FloatArray
    ) -> FloatArray:
        """``A^T W (c - A_fixed x_fixed)`` over the free unknowns."""
        xf = np.append(np.where(self.fixed, x_fixed, 0.0), 0.0)
        c = const - np.sum(vals * xf[np.where(self.cols >= 0, self.cols, self.n)], axis=1)
        contrib = vals * (weights * c)[:, None]
        ok = self.fc >= 0
        out = np.bincount(self.fc[ok], weights=contrib[ok], minlength=self.nf).astype(np.float64)
        return out

    def factor(self, vals: FloatArray, weights: FloatArray) -> FloatArray:
        """Cholesky factor of the banded normal matrix (LAPACK pbtrf)."""
        ab = self.normal_band(vals, weights)
        try:
            return np.asarray(scipy.linalg.cholesky_banded(ab, lower=False, check_finite=False))
        except np.linalg.LinAlgError:
            raise WarpError("the warp system is singular (the mesh is disconnected?)") from None

    def solve(
        self,
        vals: FloatArray,
        const: FloatArray,
        weights: FloatArray,
        x_fixed: FloatArray,
        factor: FloatArray | None = None,
    ) -> FloatArray:
        """Minimiser x (n,), with fixed unknowns copied from ``x_fixed``."""
        cb = self.factor(vals, weights) if factor is None else factor
        b = self.rhs(vals, const, weights, x_fixed)
        xs = scipy.linalg.cho_solve_banded((cb, False), b, check_finite=False)
        x = np.array(x_fixed, dtype=np.float64, copy=True)
        x[~self.fixed] = xs
        if not np.all(np.isfinite(x)):
            raise WarpError("the warp solve produced non-finite values")
        return x
