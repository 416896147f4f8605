"""The depth -> surface pipeline as one object: :class:`SurfaceEstimator`."""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.cuts import (
    aim_node,
    cut_at_jumps,
    cut_lattice,
    keep_aimed_piece,
    keep_edges,
)
from adaproj_edge.geometry.depth.fits import smooth_lattice
from adaproj_edge.geometry.depth.images import clean_images, sampled_images, smooth_images
from adaproj_edge.geometry.depth.lattice import (
    fill_holes,
    lattice_uv,
    node_confidence,
    node_spacing_m,
    reject_spikes,
    supersampling_at,
)
from adaproj_edge.geometry.depth.rays import intersect_images
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.depth.workspace import Workspace
from adaproj_edge.geometry.surface import Surface


@dataclass(frozen=True)
class SurfaceEstimate:
    """A Surface lattice with per-node confidence.

    Attributes
    ----------
    surface : Surface
        Points (rows, cols, 3) in frame P, NaN where unknown.
    confidence : (rows, cols) float32
        In [0, 1]; 0 where there is no point.
    filled : (rows, cols) bool
        Nodes filled in from neighbours (a hole in the depth data).
    frames : int
        Depth frames averaged into this estimate.
    seen : float or None
        Fraction of lattice nodes the depth frame measured, before the pieces off the
        aim were dropped at depth jumps (None: as :attr:`coverage`).
    raw : (fine rows, fine cols, 3) float array or None
        The newest frame's depth before any smoothing across the lattice: points in
        frame P on the rays of a lattice ``raw_step`` times finer (the surface's nodes
        are every ``raw_step``-th), NaN where the frame has no depth there. Plane
        snapping judges and fits planes on these (:mod:`~adaproj_edge.geometry.planes`).
    raw_step : int
        How much finer :attr:`raw` is than the surface's lattice.
    """

    surface: Surface
    confidence: NDArray[np.float32]
    filled: BoolArray
    frames: int = 1
    seen: float | None = None
    raw: FloatArray | None = None
    raw_step: int = 1

    @property
    def coverage(self) -> float:
        """Fraction of lattice nodes with a point."""
        return self.surface.valid_fraction

    @property
    def seen_coverage(self) -> float:
        """Fraction of lattice nodes the frame measured (a frame that sees a room is not
        a dropout because the piece under the aim is small)."""
        return self.coverage if self.seen is None else self.seen

    @property
    def mean_confidence(self) -> float:
        """Mean confidence over the whole lattice (unknown nodes count as 0)."""
        return float(np.mean(self.confidence))

    def summary(self) -> dict[str, float | int]:
        """Coverage, mean confidence, filled node count and frames, for telemetry (rounded)."""
        return {
            "coverage": round(self.coverage, 4),
            "confidence": round(self.mean_confidence, 4),
            "filled": int(self.filled.sum()),
            "frames": self.frames,
        }


class SurfaceEstimator:
    """Depth frames -> :class:`SurfaceEstimate`, the whole pipeline of
    :mod:`adaproj_edge.geometry.depth`.

    It owns its state: the scratch arrays reused from frame to frame
    (:class:`~adaproj_edge.geometry.depth.workspace.Workspace`) and the lattice rays of
    the shapes asked for. One estimator serves one thread.

    Parameters
    ----------
    calibration : Calibration
        Depth model, projector and ``T_P_D``.
    settings : DepthSettings, optional
    """

    def __init__(self, calibration: Calibration, settings: DepthSettings | None = None) -> None:
        self.calibration = calibration
        self.settings = settings or DepthSettings()
        self.sensor = SensorModel.of(calibration.depth, self.settings.sensor)
        self.work = Workspace()
        self._rays: dict[tuple[int, int], FloatArray] = {}
        # the last lattice's measured fraction, before the pieces off the aim went
        self.seen = 0.0
        # the last frame's depth along the fine lattice's rays before smoothing, and
        # how much finer that lattice is (see SurfaceEstimate.raw)
        self.raw_depth: FloatArray | None = None
        self.raw_step = 1
        # the newest frame's fine raw depth, support, step, jumps and lattice shape
        self._last: tuple[FloatArray, FloatArray, int, BoolArray | None, tuple[int, int]] | None = (
            None
        )

    def rays(self, shape: tuple[int, int]) -> FloatArray:
        """Projector rays (rows, cols, 3) of the lattice ``shape`` (read-only, kept)."""
        rays = self._rays.get(shape)
        if rays is None:
            if len(self._rays) > 16:
                self._rays.clear()
            p = self.calibration.projector
            rays = p.rays(lattice_uv(p, shape))
            rays.setflags(write=False)
            self._rays[shape] = rays
        return rays

    def estimate(self, depth_m: FloatArray, shape: tuple[int, int] = (21, 21)) -> SurfaceEstimate:
        """The Surface at a (rows, cols) lattice of projector rays from one depth frame.

        Parameters
        ----------
        depth_m : (h, w) float array
            Depth in metres in frame D (z along the optical axis), NaN or 0 = invalid.
        shape : (rows, cols)
            Lattice size: the warp grid's vertex count (e.g. (21, 21) for a 20x20
            grid), or a fine lattice for a dense surface (see
            :func:`~adaproj_edge.geometry.depth.lattice.dense_shape`).
        """
        s, sup, filled = self.lattice_depths(depth_m, shape)
        return self._estimate_of(s, sup, filled)

    def re_estimate(self, raw_depth: FloatArray) -> SurfaceEstimate:
        """The newest frame's estimate again, from ``raw_depth`` in the place of its
        fine lattice's raw depth: the same rays' depths averaged over the frames the
        device was still for (:class:`~adaproj_edge.geometry.depth.temporal.SurfaceFilter`).
        Smoothing, cuts and fills then judge shape against the averaged noise, so the
        longer the device is still, the less of a curved surface the smoothing takes
        for noise.

        Parameters
        ----------
        raw_depth : (fine rows, fine cols) float array
            Depth along the rays of :attr:`raw_depth`'s lattice, NaN where unknown.

        Raises
        ------
        ValueError
            Before any frame, or when ``raw_depth`` is not that lattice's shape.
        """
        last = self._last
        if last is None or np.shape(raw_depth) != last[0].shape:
            raise ValueError("re_estimate needs the newest frame's fine lattice shape")
        _, sup, k, jumps, shape = last
        s = np.asarray(raw_depth, dtype=np.float64)
        s, sup, filled = self._lattice_of(s, sup, k, jumps, shape)
        return self._estimate_of(s, sup, filled)

    def _estimate_of(self, s: FloatArray, sup: FloatArray, filled: BoolArray) -> SurfaceEstimate:
        """The estimate of lattice depths ``s``, support ``sup`` and ``filled`` nodes."""
        p = self.calibration.projector
        points = self.rays(s.shape) * s[..., None]
        conf = node_confidence(
            points, np.where(filled, 0.5, sup), filled, self.calibration, self.settings
        )
        surface = Surface(points.astype(np.float32), p, {"source": "depth"})
        raw = None
        if self.raw_depth is not None:
            r = self.raw_depth
            raw = self.rays(r.shape) * r[..., None]
        est = SurfaceEstimate(
            surface, conf, filled & np.isfinite(s), seen=self.seen, raw=raw, raw_step=self.raw_step
        )
        meta = {"source": "depth", **est.summary()}
        del meta["frames"]  # the estimate's own field, not the surface's
        return replace(est, surface=replace(surface, meta=meta))

    def lattice_depths(
        self, depth_m: FloatArray, shape: tuple[int, int]
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Steps 1-4: the depth along each lattice ray (rows, cols) (NaN where
        unknown), the support there and the filled nodes."""
        cal, settings, work = self.calibration, self.settings, self.work
        z = np.asarray(depth_m, dtype=np.float64)
        if z.shape != (cal.depth.height, cal.depth.width):
            z = cv2.resize(
                np.nan_to_num(z, nan=0.0).astype(np.float32),
                (cal.depth.width, cal.depth.height),
                interpolation=cv2.INTER_NEAREST,
            ).astype(np.float64)
        ok, z32, jumps = clean_images(
            z, settings, True, work, self.sensor if settings.cut else None
        )
        smoothed = smooth_images(ok, z32, settings.smooth_sigma_px, work)
        images = sampled_images(*smoothed, settings, work)
        p = cal.projector
        k = supersampling_at(p, shape, images.z_any, settings)
        fine = ((shape[0] - 1) * k + 1, (shape[1] - 1) * k + 1)
        s, sup = intersect_images(self.rays(fine), images, cal, settings)
        s = reject_spikes(s, settings.spike_rel)
        self._last = (s, sup, k, jumps, shape)
        return self._lattice_of(s, sup, k, jumps, shape)

    def _lattice_of(
        self,
        s: FloatArray,
        sup: FloatArray,
        k: int,
        jumps: BoolArray | None,
        shape: tuple[int, int],
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Steps 4 on: the fine lattice's raw depth ``s`` (support ``sup``, ``k`` times
        finer than ``shape``; ``jumps`` the frame's depth jumps) smoothed, cut at
        silhouettes and filled: the lattice's depths, support and filled nodes."""
        cal, settings, work = self.calibration, self.settings, self.work
        p = cal.projector
        raw = s[::k, ::k]
        self.raw_depth, self.raw_step = s, k
        if np.isfinite(s).any():
            spacing = node_spacing_m(p, (s.shape[0], s.shape[1]), float(np.nanmedian(s)))
            sigma = min(settings.smooth_m / spacing, settings.smooth_max_nodes)
            s = smooth_lattice(
                s,
                sigma,
                settings.smooth_scales,
                settings.smooth_accept,
                step=k,
                work=work,
                floor=settings.step_floor * self.sensor.inverse_step,
            )
        else:
            s = s[::k, ::k]
        blocked = None
        if settings.cut:
            s = keep_edges(s, raw, self.sensor, settings.jump_sigmas)
            s, blocked = cut_lattice(s, self.sensor, settings.jump_sigmas, settings.jump_slope)
            if jumps is not None:
                s, dropped = cut_at_jumps(
                    s, self.rays(shape), cal, jumps, self.sensor, settings.jump_sigmas
                )
                blocked |= dropped
        s, filled = fill_holes(
            s,
            settings.max_hole_nodes,
            blocked,
            self.sensor if settings.cut else None,
            settings,
            node_spacing_m(p, shape, 1.0),
        )
        self.seen = float(np.mean(np.isfinite(s)))
        if settings.cut:
            K = p.K
            s = keep_aimed_piece(s, aim_node(shape, (K[0, 2], K[1, 2]), (p.width, p.height)))
            filled &= np.isfinite(s)
        return s, sup[::k, ::k], filled


def estimate_surface(
    depth_m: FloatArray,
    calibration: Calibration,
    shape: tuple[int, int] = (21, 21),
    settings: DepthSettings | None = None,
) -> SurfaceEstimate:
    """The Surface at a (rows, cols) lattice of projector rays from one depth frame (a
    one-off :class:`SurfaceEstimator`; a device keeps one).

    Parameters
    ----------
    depth_m : (h, w) float array
        Depth in metres in frame D (z along the optical axis), NaN or 0 = invalid.
    calibration : Calibration
        Depth model, projector and ``T_P_D``.
    shape : (rows, cols)
        Lattice size: the warp grid's vertex count (e.g. (21, 21) for a 20x20 grid),
        or a fine lattice for a dense surface (see
        :func:`~adaproj_edge.geometry.depth.lattice.dense_shape`).
    """
    return SurfaceEstimator(calibration, settings).estimate(depth_m, shape)
