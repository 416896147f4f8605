"""Estimates averaged over time while the device is still."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.depth.estimate import SurfaceEstimate, SurfaceEstimator
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.surface import Surface


class SurfaceFilter:
    """Averages estimates over time while the device is still; restarts when it moves.

    Per node, a running mean of the depth along the ray (so a point stays on its ray),
    weighted by confidence; a node whose new depth jumps more than ``jump_rel`` of its
    depth starts over. At most ``max_frames`` frames are kept in the mean. The raw depth
    before smoothing (:attr:`SurfaceEstimate.raw`) is averaged the same way, per ray of
    its finer lattice and with equal weights, so a plane fitted to it has the noise of
    the averaged frames, not of the newest one.

    Given the ``estimator`` that made the estimates, the averaged raw depth (where the
    newest frame sees) is what is smoothed, cut and filled again
    (:meth:`~adaproj_edge.geometry.depth.estimate.SurfaceEstimator.re_estimate`),
    rather than the smoothed lattices being averaged: the smoothing tells a curved
    surface from noise against the averaged noise, so averaging removes its bias (a
    column's curvature taken for noise) as well as the noise. Each estimate must be
    passed here right after the estimator made it.
    """

    def __init__(
        self,
        max_frames: int = 30,
        jump_rel: float = 0.03,
        estimator: SurfaceEstimator | None = None,
    ) -> None:
        self.max_frames = max_frames
        self.jump_rel = jump_rel
        self.estimator = estimator
        self._s: FloatArray | None = None
        self._w: FloatArray | None = None
        self._c: FloatArray | None = None
        self._n = 0
        self._raw_z: FloatArray | None = None  # the raw depth's running mean, its frames
        self._raw_w: FloatArray | None = None
        self.current: SurfaceEstimate | None = None

    def reset(self) -> None:
        """Forget the running mean; the next estimate starts it over."""
        self._s = self._w = self._c = None
        self._raw_z = self._raw_w = None
        self._n = 0
        self.current = None

    def _raw(self, est: SurfaceEstimate, restart: bool) -> FloatArray | None:
        """The raw points (fine rows, fine cols, 3) averaged along their rays over the
        frames kept (a ray whose depth jumped starts over; one the newest frame missed
        keeps its mean); restarted with ``restart`` or a new fine lattice."""
        raw = est.raw
        if raw is None:
            self._raw_z = self._raw_w = None
            return None
        z = raw[..., 2]
        ok = np.isfinite(z)
        if restart or self._raw_z is None or self._raw_w is None or self._raw_z.shape != z.shape:
            self._raw_z, self._raw_w = z.copy(), ok.astype(np.float64)
            return raw
        old = self._raw_z
        with np.errstate(invalid="ignore"):
            jump = ok & np.isfinite(old) & (np.abs(z - old) > self.jump_rel * old)
        w_old = np.where(jump, 0.0, np.minimum(self._raw_w, self.max_frames - 1))
        total = w_old + ok
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = (np.where(w_old > 0, old, 0.0) * w_old + np.where(ok, z, 0.0)) / total
        self._raw_z, self._raw_w = np.where(total > 0, mean, np.nan), total
        p = est.surface.projector
        out: FloatArray = p.rays(lattice_uv(p, z.shape)) * self._raw_z[..., None]
        return out

    def update(self, est: SurfaceEstimate, still: bool) -> SurfaceEstimate:
        """Fold ``est`` into the running mean and return the averaged estimate.

        Parameters
        ----------
        est : SurfaceEstimate
            The newest estimate; its lattice shape must stay the same for it to be averaged.
        still : bool
            Whether the device has been still since the previous estimate; when not (or
            when the lattice shape changed) the mean restarts from ``est``.

        Returns
        -------
        SurfaceEstimate
            Depths along each node's ray averaged with confidence weights (a node that
            jumped starts over), the weighted confidence, and ``frames`` the number of
            frames in the mean (at most ``max_frames``). Also kept as :attr:`current`.
        """
        pts = est.surface.points.astype(np.float64)
        s_new = pts[..., 2]
        c_new = est.confidence.astype(np.float64)
        if not still or self._s is None or self._s.shape != s_new.shape:
            self._s, self._c = s_new.copy(), c_new.copy()
            self._w = np.where(np.isfinite(s_new), np.maximum(c_new, 1e-3), 0.0)
            self._n = 1
            self._raw(est, True)
            self.current = est
            return est
        assert self._w is not None and self._c is not None
        with np.errstate(invalid="ignore"):
            both = np.isfinite(s_new) & np.isfinite(self._s)
            jump = both & (np.abs(s_new - self._s) > self.jump_rel * self._s)
        w_new = np.where(np.isfinite(s_new), np.maximum(c_new, 1e-3), 0.0)
        cap = np.max(w_new) * self.max_frames if w_new.size else 1.0
        w_old = np.where(jump, 0.0, np.minimum(self._w, cap))
        total = w_old + w_new
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(
                total > 0,
                (np.nan_to_num(self._s) * w_old + np.nan_to_num(s_new) * w_new) / total,
                np.nan,
            )
            c = np.where(total > 0, (self._c * w_old + c_new * w_new) / total, 0.0)
        self._n = min(self._n + 1, self.max_frames)
        raw = self._raw(est, False)
        if self.estimator is not None and est.raw is not None and self._raw_z is not None:
            seen = np.isfinite(est.raw[..., 2])
            again = self.estimator.re_estimate(np.where(seen, self._raw_z, np.nan))
            s = again.surface.points[..., 2].astype(np.float64)
            c = again.confidence.astype(np.float64)
            self._s, self._w, self._c = s, np.where(np.isfinite(s), total, 0.0), c
            self.current = replace(again, frames=self._n, raw=raw)
            return self.current
        self._s, self._w, self._c = s, total, c
        dirs = est.surface.projector.rays(lattice_uv(est.surface.projector, s.shape))
        surface = Surface(
            (dirs * s[..., None]).astype(np.float32), est.surface.projector, dict(est.surface.meta)
        )
        filled = est.filled & ~np.isfinite(self._s) | (est.filled & (w_old == 0))
        self.current = SurfaceEstimate(
            surface,
            c.astype(np.float32),
            filled,
            self._n,
            raw=raw,
            raw_step=est.raw_step,
        )
        return self.current
