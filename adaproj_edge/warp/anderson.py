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
    """Keeps the last ``depth`` iterates and their images.

    ``next(x, gx)`` takes the current iterate ``x`` (N,) and its image ``gx = g(x)``
    and returns the next iterate; :meth:`reset` forgets the history (call it when
    ``g`` changes).
    """

    depth: int = 3
    _f: list[FloatArray] = field(default_factory=list)
    _g: list[FloatArray] = field(default_factory=list)

    def reset(self) -> None:
        """Forget the history (``g`` has changed)."""
        self._f.clear()
        self._g.clear()

    def next(self, x: FloatArray, gx: FloatArray) -> FloatArray:
        """The accelerated next iterate (N,) from ``x`` and ``g(x)`` (both (N,))."""
        f = gx - x
        self._f.append(f)
        self._g.append(gx)
        if len(self._f) > self.depth + 1:
            del self._f[0], self._g[0]
        m = len(self._f) - 1
        if m < 1:
            return gx
        df = np.diff(np.stack(self._f), axis=0)  # (m, N)
        # the least-squares mix by its (small) normal equations, lightly regularised
        gram = df @ df.T
        gram[np.diag_indices_from(gram)] *= 1.0 + 1e-10
        try:
            gamma = np.linalg.solve(gram, df @ f)
        except np.linalg.LinAlgError:
            self.reset()
            return gx
        out: FloatArray = gx - gamma @ np.diff(np.stack(self._g), axis=0)
        if not np.all(np.isfinite(out)):
            self.reset()
            return gx
        return out
