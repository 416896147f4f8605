"""The committed session fixtures: content, golden replay outputs, deterministic replay."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.session.digest import tracking_digest
from adaproj_edge.session.player import Replay
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.track import track_surface

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "sessions"
NAMES = ["corner", "cylinder", "sphere", "mesh-sphere"]


@pytest.mark.parametrize("name", NAMES)
def test_fixture_has_movement_and_button_presses(name: str) -> None:
    s = read_session(FIXTURES / f"{name}.mcap")
    assert not s.truncated
    assert len(s.depth) == 15 and s.depth[0].depth_mm.shape == (400, 640)
    assert len(s.imu) > 600
    presses = [b for b in s.button if b.pressed]
    assert len(presses) == 2 and len(s.button) == 4
    pos = np.array([p.position for p in s.truth_poses])
    assert np.ptp(pos, axis=0).max() > 0.01  # the device moved by more than a centimetre
    spec = s.truth_surface_spec()
    assert spec is not None and spec["kind"] in ("analytic", "mesh")
    assert s.metadata["session"]["source"] == "simulator"


def test_fixtures_are_small() -> None:
    total = sum(p.stat().st_size for p in FIXTURES.iterdir())
    assert total < 5_000_000


@pytest.mark.parametrize("name", NAMES)
def test_replay_matches_the_golden_outputs(name: str) -> None:
    golden = json.loads((FIXTURES / "golden.json").read_text())[name]
    got = tracking_digest(FIXTURES / f"{name}.mcap", (21, 21))
    assert len(got) == len(golden)
    for g, w in zip(got, golden, strict=True):
        assert g["t_ns"] == w["t_ns"] and g["still"] == w["still"]
        assert g["coverage"] == pytest.approx(w["coverage"], abs=1e-6)
        assert g["confidence"] == pytest.approx(w["confidence"], abs=1e-5)
        for a, b in zip(g["z_mm"], w["z_mm"], strict=True):
            assert (a is None) == (b is None)
            if a is not None:
                assert a == pytest.approx(b, abs=0.01)


def test_replaying_twice_gives_identical_results() -> None:
    runs = []
    for _ in range(2):
        r = Replay(FIXTURES / "corner.mcap")
        runs.append(
            [
                (t.frame.sensor_ns, t.still, t.estimate.surface.points.tobytes(), r.clock.now_ns())
                for t in track_surface(r.events(), r.calibration)
            ]
        )
    assert runs[0] == runs[1]
