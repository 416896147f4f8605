"""The hand-held figures (issue 14) on a short simulated session made here: a wall at
1.5 m, hand tremor 0.15 degrees RMS, replayed with stabilisation and without.

The scorer follows every refresh onto the simulator's true surface at the true pose
of the moment it is lit; "off" is the same session replayed with ``--no-stabilise``.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import pytest

from adaproj_edge.app.replay import ReplayOptions, replay_session
from adaproj_edge.cli import main
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session

SECONDS = 3.5


@functools.cache
def session(tmp: str) -> Path:
    path = Path(tmp) / "wall-tremor.mcap"
    hand = HandMotion(SECONDS, seed=30, tremor_deg=0.15)
    settings = SimulationSettings(seconds=SECONDS, depth_fps=15.0, seed=30, motion=hand)
    simulate_session(Scene.load("plane"), path, Calibration.default(), settings)
    return path


@pytest.fixture(scope="module")
def wall(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return session(str(tmp_path_factory.mktemp("handheld")))


@functools.cache
def replayed(path: Path, stabilise: bool) -> dict[str, Any]:
    return replay_session(path, None, ReplayOptions(stabilise=stabilise))


def test_tremor_is_cancelled_on_the_wall(wall: Path) -> None:
    on = replayed(wall, True)["handheld"]
    off = replayed(wall, False)["handheld"]
    assert on["scored_refreshes"] > 100 and off["scored_refreshes"] > 100
    # today's runtime (no stabilisation) moves the picture by millimetres every refresh
    assert off["jitter_mm_rms"] > 1.0
    assert on["jitter_mm_rms"] <= 0.2 * off["jitter_mm_rms"]
    # the scorer's own "not stabilised" view of the stabilised run agrees with the
    # run that was not stabilised, within the difference of their rendered frames
    assert on["jitter_off_mm_rms"] == pytest.approx(off["jitter_mm_rms"], rel=0.3)


def test_no_stabilise_shows_the_frames_as_rendered(wall: Path) -> None:
    off = replayed(wall, False)["handheld"]
    assert off["margin"] == 0.0
    assert off["jitter_mm_rms"] == off["jitter_off_mm_rms"]
    assert off["motion_to_photon_ms"]["n"] == 0  # nothing corrected: no IMU -> photon


def test_motion_to_photon_is_counted_at_every_refresh(wall: Path) -> None:
    h = replayed(wall, True)["handheld"]
    refreshes = h["refreshes"]
    assert abs(refreshes - 60 * SECONDS) <= 3  # 60 Hz from the first record to the last
    m = h["motion_to_photon_ms"]
    assert refreshes - 3 <= m["n"] <= refreshes  # every refresh after the first sample
    # a sample is at most a FIFO read (2.5 ms) old when the step starts, lead_s (8 ms)
    # before the sync
    assert 8.0 <= m["median"] <= m["p95"]


def test_replays_with_refreshes_are_deterministic(wall: Path) -> None:
    # the second replay without the distortion scores: they change nothing else
    a = replayed(wall, True)
    b = replay_session(wall, None, ReplayOptions(distortion=False))
    assert a["frames"] == b["frames"]
    for key in ("jitter_mm_rms", "jitter_off_mm_rms", "upright_error_deg_max", "refreshes"):
        assert a["handheld"][key] == b["handheld"][key]
    assert a["distortion"] and not b["distortion"]


def test_replay_command_writes_the_handheld_picture(
    wall: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(["replay", str(wall), "--out", str(out), "--no-cache"]) == 0
    printed = capsys.readouterr().out
    assert "refreshes" in printed and "jitter" in printed and "handheld.png" in printed
    s = json.loads((out / "summary.json").read_text())
    assert s["handheld"]["jitter_mm_rms"] is not None
    assert (out / "handheld.png").stat().st_size > 1000
    assert main(["replay", str(wall), "--no-stabilise", "--no-score"]) == 0
    assert "IMU sample -> display" not in capsys.readouterr().out
