"""Running the depth -> surface pipeline over a session's records.

This is how the device consumes its sensors (and how tests replay them): every depth
frame becomes a surface estimate, averaged over time while the IMU says the device
is still. The result depends only on the records, never on wall-clock time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.estimate import SurfaceEstimate, SurfaceEstimator
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.depth.temporal import SurfaceFilter
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.motion.tracker import is_still
from adaproj_edge.session.codec import Record

STILL_WINDOW_NS = 200_000_000


@dataclass(frozen=True)
class Tracked:
    """The estimate after depth frame ``frame`` (and whether the device was still)."""

    frame: DepthFrame
    still: bool
    estimate: SurfaceEstimate


def track_surface(
    records: Iterable[Record],
    calibration: Calibration,
    shape: tuple[int, int] = (21, 21),
    settings: DepthSettings | None = None,
) -> Iterator[Tracked]:
    """Surface estimates, one per depth frame, in record order."""
    imu: deque[ImuSample] = deque()
    estimator = SurfaceEstimator(calibration, settings)
    filt = SurfaceFilter(estimator=estimator)
    for rec in records:
        if isinstance(rec, ImuSample):
            imu.append(rec)
            continue
        if not isinstance(rec, DepthFrame):
            continue
        while imu and imu[0].sensor_ns < rec.sensor_ns - STILL_WINDOW_NS:
            imu.popleft()
        window = [s for s in imu if s.sensor_ns <= rec.sensor_ns]
        still = is_still(
            np.array([s.gyro for s in window]).reshape(-1, 3),
            np.array([s.accel for s in window]).reshape(-1, 3),
        )
        est = estimator.estimate(rec.metres(), shape)
        yield Tracked(rec, still, filt.update(est, still))
