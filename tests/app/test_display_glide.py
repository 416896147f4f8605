"""The display loop's glide between rendered frames: slow held still (a re-placement
eases in), quick while the device is turned on purpose (frames come every
``moving_interval_s`` and a slow glide would leave the content behind the device)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from adaproj_edge.app.display_loop import DisplayLoop, Shown
from adaproj_edge.app.settings import DisplaySettings
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.warp.engine import standard_warp
from adaproj_edge.warp.warpmap import Grid, Warp


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


def _placed(warp: Warp, scale: float, shift_px: float) -> Warp:
    """``warp`` with its content shown ``scale`` times as large, ``shift_px`` right."""
    a = warp.content_size[0] / warp.projector.width  # content pixels per projector pixel
    centre = np.array(warp.content_size, dtype=np.float64) / 2
    xy = (warp.image_xy - centre) / scale + centre
    xy[..., 0] -= a * shift_px / scale
    return replace(warp, image_xy=xy)


@pytest.mark.parametrize(
    ("old_frames", "rate", "glides"),
    [(1, (0.0, 0.0, 0.0), True), (4, (0.0, 0.0, 0.0), True), (4, (0.0, 0.3, 0.05), False)],
)
def test_a_re_placement_glides_in_unless_the_device_is_turned(
    old_frames: int, rate: tuple[float, float, float], glides: bool
) -> None:
    """A new placement a fifth smaller and 150 px away (three margins), as the holes
    of a single-frame surface give: when the hand stops after a move and the surface
    averaged over 4 depth frames replaces the last single-frame one, or while the hand
    holds still and a tremor over the motion tracker's line keeps single-frame
    surfaces coming, it glides in; while the device is turned on purpose it is shown
    at once (``max_glide``: the frame follows the device)."""
    loop = _loop()
    _turn(loop, rate, 0.5)
    p = Projector.default()
    base = standard_warp(p, (640, 400), Grid())
    frame = np.zeros((p.height, p.width, 3), np.uint8)
    t = round(0.5e9)
    loop.publish(frame, [], Shown(1, "content-free", _placed(base, 0.8, 150.0), "a", old_frames), t)
    loop.publish(frame, [], Shown(2, "content-aware", base, "a", 4), t + round(1e9 / 15))
    glided = not np.allclose(loop._glide, np.eye(3))
    assert glided is glides


def test_a_re_placement_glides_in_while_a_strong_tremor_lifts_the_deliberate_rate() -> None:
    """The simulated hand held still at 0.5 degrees RMS of tremor: what the low-pass
    leaves of its rate goes over ``moving_rate`` now and then. A re-placement published
    at such a moment (the one above, three margins) was taken for a frame following a
    deliberate turn and shown at once (at a corner: 188 mm, jitter ratio 0.61); the
    device is not turned (the stabiliser's ``turning``), so it glides in."""
    loop = _loop()
    seconds = 3.0
    t = np.arange(0, seconds, 1 / 416)
    _, rate = HandMotion(seconds, seed=0, tremor_deg=0.5, hold_after=0).imu_truth(t)
    moving_rate = loop.settings.stabiliser.moving_rate
    for k in range(len(t)):
        t_ns = round(t[k] * 1e9)
        loop.on_imu(ImuSample(t_ns, t_ns, (0.0, -9.81, 0.0), tuple(rate[k])))
        if t[k] > 1.0 and loop.stabiliser.deliberate_rate > moving_rate:
            break
    assert loop.stabiliser.deliberate_rate > moving_rate  # the rate alone: "moving"
    p = Projector.default()
    base = standard_warp(p, (640, 400), Grid())
    frame = np.zeros((p.height, p.width, 3), np.uint8)
    loop.publish(frame, [], Shown(1, "content-free", _placed(base, 0.8, 150.0), "a", 1), t_ns)
    loop.publish(frame, [], Shown(2, "content-free", base, "a", 1), t_ns + 1)
    assert not np.allclose(loop._glide, np.eye(3))


def test_a_re_placement_is_judged_where_the_content_is() -> None:
    """Held still, content shown at half the frame's width re-placed at 0.3 of it (a
    re-capture of a corner puts the content on its other wall): its points move 0.1
    under a tenth of the frame, far under ``max_handover_glide``, so it glides in. The
    homography's frame corners, far outside the content, move 0.3 of the frame (5/3,
    the ratio of the two scales, times their distance from the centre): judged there it
    was shown at once, a jump of centimetres (at a corner whose placement is no
    homography the corners' move is over twice the content's)."""
    loop = _loop()
    _turn(loop, (0.0, 0.0, 0.0), 0.5)
    p = Projector.default()
    base = standard_warp(p, (640, 400), Grid())
    frame = np.zeros((p.height, p.width, 3), np.uint8)
    t = round(0.5e9)
    loop.publish(frame, [], Shown(1, "content-aware", _placed(base, 0.5, 0.0), "a", 4), t)
    loop.publish(frame, [], Shown(2, "content-aware", _placed(base, 0.3, 0.0), "a", 3), t + 1)
    assert not np.allclose(loop._glide, np.eye(3))
