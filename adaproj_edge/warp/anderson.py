"""Anderson acceleration of a fixed-point iteration ``x <- g(x)``.

The content-aware alternation with a fixed salient set is a local-global iteration
(as-rigid-as-possible style): every step is cheap (one back-substitution) but the
plain iteration converges linearly, about 0.7x per step on the analytic surfaces.
Anderson's method (type II, Walker and Ni 2011) mixes the last few steps so that
the residual of their combination is least: on those surfaces it reaches 0.05 px in
about five steps instead of eleven. It only changes the path, not the fixed point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from adaproj_edge.arrays import FloatArray


@dataclass
class Anderson:
    """Keeps the differences of the last ``depth + 1`` residuals and images.

    ``next(x, gx)`` takes the current iterate ``x`` (N,) and its image ``gx = g(x)``
    and returns the next iterate; :meth:`reset` forgets the history (call it when
    ``g`` changes).
    """

    depth: int = 3
    _last: tuple[FloatArray, FloatArray] | None = None  # the last residual and image
    _df: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))  # (depth, N)
    _dg: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    _m: int = 0  # rows of _df, _dg in use

    def reset(self) -> None:
        """Forget the history (``g`` has changed)."""
        self._last = None
        self._m = 0

    def next(self, x: FloatArray, gx: FloatArray) -> FloatArray:
        """The accelerated next iterate (N,) from ``x`` and ``g(x)`` (both (N,))."""
        f = gx - x
        last, self._last = self._last, (f, gx)
        if last is None:
            return gx
        if self._df.shape != (self.depth, f.size):
            self._df = np.empty((self.depth, f.size))
            self._dg = np.empty((self.depth, f.size))
        if self._m == self.depth:  # the oldest difference goes
            self._df[:-1] = self._df[1:]
            self._dg[:-1] = self._dg[1:]
            self._m -= 1
        np.subtract(f, last[0], out=self._df[self._m])
        np.subtract(gx, last[1], out=self._dg[self._m])
        self._m += 1
        df, dg = self._df[: self._m], self._dg[: self._m]
        # the least-squares mix by its (small) normal equations, lightly regularised
        gram = df @ df.T
        gram.flat[:: self._m + 1] *= 1.0 + 1e-10
        try:
            gamma = np.linalg.solve(gram, df @ f)
        except np.linalg.LinAlgError:
            self.reset()
            return gx
        out: FloatArray = gx - gamma @ dg
        if not np.all(np.isfinite(out)):
            self.reset()
            return gx
        return out
