"""The runtime takes the calibration's accelerometer offset out of every reading."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample


def test_the_calibrated_offset_does_not_tilt_up() -> None:
    offset = np.array([0.17, 0.0, -0.05])  # 0.17 m/s^2 across gravity: 1 degree
    cal = replace(Calibration.default(), accel_offset=offset)
    clock = VirtualClock(1_000_000_000)
    display = MemoryDisplay(cal.projector.width, cal.projector.height)
    rt = Runtime(cal, display, clock, [builtin_item()], content_map_fn=mask_content_map)
    rt.boot()
    specific_force = np.array([0.0, -9.80665, 0.0])  # held level and still
    read = specific_force + offset
    for k in range(2 * 416):
        t = 1_000_000_000 + round(k * 1e9 / 416)
        rt.on_imu(ImuSample(t, t, tuple(read), (0.0, 0.0, 0.0), 30.0))
    up = rt.upright.up
    assert up is not None
    tilt = np.degrees(np.arccos(np.clip(up @ np.array([0.0, -1.0, 0.0]), -1.0, 1.0)))
    # noise-free readings: what is left is the filters' arithmetic and the dead band
    # (0.3 deg); the offset alone would tilt it by atan(0.17 / 9.8) = 1.0 deg
    assert tilt < 0.31, tilt
