"""The display loop's glide between rendered frames: slow held still (a re-placement
eases in), quick while the device is turned on purpose (frames come every
``moving_interval_s`` and a slow glide would leave the content behind the device)."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.app.display_loop import DisplayLoop
from adaproj_edge.app.settings import DisplaySettings
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample


def _loop() -> DisplayLoop:
    p = Projector.default()
    return DisplayLoop(
        MemoryDisplay(p.width, p.height), p, np.eye(3), DisplaySettings(), Telemetry(100)
    )


def _turn(loop: DisplayLoop, rate: tuple[float, float, float], seconds: float) -> None:
    for k in range(round(seconds * 416)):
        t = round(k * 1e9 / 416)
        loop.on_imu(ImuSample(t, t, (0.0, -9.81, 0.0), rate))


def test_the_glide_is_slow_held_still() -> None:
    loop = _loop()
    _turn(loop, (0.0, 0.0, 0.0), 0.5)
    assert loop._glide_tau() == pytest.approx(loop.settings.glide_s, rel=1e-6)


def test_the_glide_is_quick_while_the_device_is_turned() -> None:
    loop = _loop()
    _turn(loop, (0.0, 0.3, 0.05), 0.5)  # a deliberate turn, 17 degrees a second
    s = loop.settings
    assert loop._glide_tau() == pytest.approx(s.glide_moving_s, rel=0.1)
    assert s.glide_moving_s < s.glide_s
