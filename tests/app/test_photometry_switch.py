"""The brightness gain on the device: off unless the board turns it on (a checked
flag), made once per pose and kept with it (a cached pose costs no new gain), and
applied to every frame the output renders."""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest

from adaproj_edge.app.display_loop import DisplayLoop
from adaproj_edge.app.live import board_settings
from adaproj_edge.app.output import Output
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.status import Faults
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.app.warps import WarpSource
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.irradiance import Vignetting
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.render.frame import render_frame
from adaproj_edge.render.photometry import PhotometrySettings, apply_gain
from adaproj_edge.warp.engine import WarpSettings
from tests.hal.test_board import write_board

SIZE = (800, 600)


def test_the_board_switch_is_off_by_default_and_checked(tmp_path: Path) -> None:
    assert not Board.load("rpi5-oakd").display.compensate
    assert board_settings(Board.load("rpi5-oakd"), AppSettings()).photometry is None
    on = Board.load(write_board(tmp_path, "[display]\ncompensate = true\n"))
    got = board_settings(on, AppSettings()).photometry
    assert got == PhotometrySettings(scale=AppSettings().map_scale)
    own = PhotometrySettings(evenness=1.02)  # settings given explicitly win
    assert board_settings(on, AppSettings(photometry=own)).photometry is own
    with pytest.raises(InputError) as e:
        Board.load(write_board(tmp_path, "[display]\ncompensate = 1\n"))
    assert "[display] compensate" in str(e.value) and "true or false" in str(e.value)


def test_a_pose_keeps_its_gain() -> None:
    s = simulate_surface("corner", Projector.default(640, 400))
    ws = WarpSettings(mode="content")
    o = np.zeros(3)
    off = WarpSource(s.projector, AppSettings(), Telemetry(100))
    entry, _ = off.pose(s, 5, 0, o, SIZE, ws)
    assert off.gain(entry, s) is None and entry.gain is None
    on = WarpSource(
        s.projector,
        AppSettings(photometry=PhotometrySettings(scale=4)),
        Telemetry(100),
        Vignetting((-0.3, 0.0)),
    )
    entry, hit = on.pose(s, 5, 0, o, SIZE, ws)
    gain = on.gain(entry, s)
    assert not hit and gain is not None and entry.gain is gain
    again, hit = on.pose(s, 5, 0, o, SIZE, ws)
    assert hit and again is entry and on.gain(again, s) is gain  # made once per pose
    assert on.gain(again, s, 9) is gain  # a surface averaged a little longer: kept
    assert len(on.times.samples["gain"]) == 1
    # averaged over twice the frames: made again (its crease placed better), then kept
    longer = on.gain(again, s, 10)
    assert longer is not None and longer is not gain and again.gain is longer
    assert on.gain(again, s, 12) is longer and len(on.times.samples["gain"]) == 2
    assert gain.ratio_before > 1.5 and gain.ratio_after < gain.ratio_before
    assert float(gain.light.max()) <= 1.0 < gain.ratio_before


class _Screen:
    """Keeps what is published (the display loop's place)."""

    def __init__(self) -> None:
        self.frames: list[np.ndarray] = []

    def publish(self, frame: np.ndarray, marks: list[str], shown: Any, t_ns: int) -> None:
        self.frames.append(frame.copy())


def test_the_output_applies_the_gain() -> None:
    s = simulate_surface("corner", Projector.default(640, 400))
    source = WarpSource(s.projector, AppSettings(photometry=PhotometrySettings()), Telemetry(100))
    entry, _ = source.pose(s, 5, 0, np.zeros(3), SIZE, WarpSettings(mode="content"))
    maps = source.content_free_maps(entry)
    gain = source.gain(entry, s)
    assert gain is not None
    screen = _Screen()
    t = Telemetry(100)
    out = Output(cast(DisplayLoop, screen), VirtualClock(0), Faults(), t, (640, 400))
    image = np.full((SIZE[1], SIZE[0], 3), 200, np.uint8)
    out.set(entry.warp, maps)
    first = out.render(image, "test", "content-free")
    assert first is not None
    plain = first.copy()  # the output draws into one buffer
    out.set(entry.warp, maps, gain)
    shown = out.render(image, "test", "content-free")
    assert shown is not None
    # the same calls on the same inputs: bit for bit
    assert np.array_equal(shown, apply_gain(render_frame(image, maps), gain))
    assert np.array_equal(screen.frames[0], render_frame(image, maps))
    assert np.all(shown <= plain) and np.any(shown < plain)
    assert len(t.times.samples["gain_apply"]) == 1


def test_the_replay_switch() -> None:
    """``adaproj replay --compensate`` runs with the gain at the display maps' scale;
    without it (or with ``--no-compensate``) the replay is as before."""
    from adaproj_edge.cli import build_parser
    from adaproj_edge.commands.replay import replay_settings

    parser = build_parser()
    default = replay_settings(parser.parse_args(["replay"]))
    assert default == AppSettings() and default.photometry is None
    assert replay_settings(parser.parse_args(["replay", "--no-compensate"])) == default
    on = replay_settings(parser.parse_args(["replay", "--compensate", "--no-cache"]))
    assert on.photometry == PhotometrySettings(scale=on.map_scale) and not on.caching


def test_a_measured_colour_serves_while_the_device_stays_on_its_surface(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The surface's colour measured (from simulated captures) is the gain while the
    device sees that surface, one gain per primary; on a wall 10 % nearer the gain is
    the geometric one again, and why is logged once."""
    from adaproj_edge.procam.photometric import Measured
    from adaproj_edge.render.reflectance import measure
    from adaproj_edge.render.surface_light import scaled_irradiance, simulated_captures

    s = simulate_surface("corner", Projector.default(640, 400))
    albedo = np.ones((400, 640, 3), np.float32) * np.array([0.6, 0.8, 1.0], np.float32)
    caps = simulated_captures(albedo, scaled_irradiance(s), 0.03, np.random.default_rng(0))
    response = measure(caps["black"], caps["white"], [caps[c] for c in ("blue", "green", "red")])
    h, w = response.valid.shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    uv = np.stack([(u + 0.5) * 640 / w - 0.5, (v + 0.5) * 400 / h - 0.5], -1)
    dist = np.linalg.norm(s.points_at(uv), axis=-1)
    ws = WarpSettings(mode="content")
    o = np.zeros(3)
    on = WarpSource(s.projector, AppSettings(photometry=PhotometrySettings(scale=4)), Telemetry(9))
    on.measured = Measured(response, dist, (640, 400))
    entry, _ = on.pose(s, 5, 0, o, SIZE, ws)
    gain = on.gain(entry, s)
    assert gain is not None and gain.light.ndim == 3
    # blue is returned least: it gets the most light (the tint undone)
    assert np.median(gain.light[..., 0]) > np.median(gain.light[..., 2])
    near = type(s)(s.points * 0.9, s.projector)
    entry, _ = on.pose(near, 5, 0, o, SIZE, ws)
    with caplog.at_level("INFO"):
        assert (g := on.gain(entry, near)) is not None and g.light.ndim == 2
    assert "surface colour not compensated: the device moved" in caplog.text
