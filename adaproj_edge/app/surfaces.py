"""The runtime's surface: depth frame -> estimate -> average over time -> walls snapped.

One :class:`~adaproj_edge.geometry.depth.estimate.SurfaceEstimator` (it owns its
scratch memory), one :class:`~adaproj_edge.geometry.depth.temporal.SurfaceFilter`
(averaging while the device is still: the raw depth averaged, then smoothed again by the
estimator) and the plane snapping of
:mod:`adaproj_edge.geometry.planes`.
"""

from __future__ import annotations

import numpy as np

from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.telemetry import StageTimes
from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.estimate import SurfaceEstimate, SurfaceEstimator
from adaproj_edge.geometry.depth.temporal import SurfaceFilter
from adaproj_edge.geometry.planes import RawDepth, snap_planes
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.warp.posecache import common_nodes


class SurfaceSource:
    """Surface estimates for the runtime.

    Parameters
    ----------
    calibration : Calibration
    settings : AppSettings
    times : StageTimes
        Where the stage times go ("surface", "planes").
    """

    def __init__(self, calibration: Calibration, settings: AppSettings, times: StageTimes) -> None:
        self.settings = settings
        self.times = times
        self.estimator = SurfaceEstimator(calibration, settings.depth)
        self.filter = SurfaceFilter(estimator=self.estimator)

    def estimate(self, frame: DepthFrame) -> SurfaceEstimate:
        """The surface of one depth frame at the warp grid's lattice; raises
        :class:`~adaproj_edge.errors.AdaprojError` for an unusable frame."""
        with self.times.timer("surface"):
            return self.estimator.estimate(frame.metres(), self.settings.grid_shape())

    def prepared(self, est: SurfaceEstimate) -> Surface:
        """The surface of an (averaged) estimate with its large planar pieces snapped
        onto their planes."""
        if self.settings.planes is None:
            return est.surface
        raw = None if est.raw is None else RawDepth(est.raw, est.raw_step)
        with self.times.timer("planes"):
            return snap_planes(
                est.surface, self.settings.planes, sensor=self.estimator.sensor, raw=raw
            )[0]

    def depth_problem(self, frame: DepthFrame, coverage: float) -> tuple[str, str]:
        """The fault (kind, message) of a frame whose surface covers too little."""
        d = frame.depth_mm
        seen = float(np.mean(d > 0))
        depth = self.settings.depth
        lo, hi = depth.min_depth_m * 1e3, depth.max_depth_m * 1e3
        in_range = float(np.mean((d >= lo) & (d <= hi)))
        if seen > 0.3 and in_range < 0.5 * seen:
            return "range", f"surface out of range ({lo / 1e3:g}-{hi / 1e3:g} m)"
        return "depth", f"depth dropout: surface seen on {100 * coverage:.0f} % of the frame"

    def changed(self, surface: Surface, shown_depth: FloatArray | None) -> bool:
        """Whether ``surface`` moved away from the one shown (lattice depth
        ``shown_depth``) by more than the hysteresis (median relative depth)."""
        if shown_depth is None:
            return True
        pair = common_nodes(surface.points[..., 2].astype(np.float64), shown_depth)
        if pair is None:
            return True
        z, shown = pair
        both = np.isfinite(z) & np.isfinite(shown)
        if both.sum() < 0.9 * np.isfinite(z).sum():
            return True
        rel = np.abs(z[both] - shown[both]) / shown[both]
        return bool(np.median(rel) > self.settings.hysteresis_rel)
