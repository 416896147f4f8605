"""Every committed session replayed through the runtime: goldens, distortion against
the ground truth, fault handling."""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from adaproj_edge.app.replay import ReplayOptions, replay_session
from adaproj_edge.cli import main
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.simulator import SENSOR_KEY
from tests.app.golden import GOLDEN, differences, golden_view, session_paths
from tests.distortion import allowance

# the clip session's goldens are checked in test_playback.py
NAMES = sorted(n for n in session_paths() if n != "push-clip")
# scored against the ground truth (the push session's new content has no salient region)
SIMULATED = [n for n in NAMES if n not in ("faults", "push")]


@functools.cache
def replayed(name: str) -> dict[str, Any]:
    return replay_session(session_paths()[name], None, ReplayOptions(score=name in SIMULATED))


@pytest.mark.parametrize("name", NAMES)
def test_replay_reproduces_the_goldens(name: str) -> None:
    want = json.loads(GOLDEN.read_text())[name]
    assert differences(golden_view(replayed(name)), want) == []


@pytest.mark.parametrize("name", SIMULATED)
def test_the_device_projects_and_follows_motion(name: str) -> None:
    s = replayed(name)
    assert [st for _, st in s["states"]][:4] == ["boot", "idle", "capturing", "projecting"]
    kinds = [u["kind"] for u in s["updates"]]
    assert kinds[0] == "content-aware"
    assert "content-free" in kinds  # the quick result while moving
    assert s["counters"]["content_aware"] >= 2  # the capture and the re-aim (second press)


def _displayed_vs_truth(name: str) -> list[tuple[float, float]]:
    return [(d["shown_angle_error"], d["truth_angle_error"]) for d in replayed(name)["distortion"]]


@pytest.mark.parametrize("name", SIMULATED)
def test_displayed_distortion_is_within_twice_the_true_surface_warp(name: str) -> None:
    """Plus what the session's depth may cost where the truth has none (a real sensor's
    steps: ``tests.distortion.allowance``; the committed sessions have the OAK-D's)."""
    pairs = _displayed_vs_truth(name)
    assert pairs
    sensor = read_session(session_paths()[name]).metadata["session"].get(SENSOR_KEY, "smooth")
    for shown, truth in pairs:
        assert shown <= 2 * truth + allowance(sensor), (shown, truth, sensor)


def test_fault_session_keeps_the_last_frame_and_recovers_within_a_second() -> None:
    s = replayed("faults")
    events = s["events"]
    faults = [e for e in events if e["event"] == "fault"]
    assert {e["kind"] for e in faults} == {"depth", "camera", "range", "imu"}
    # every fault clears; the sensor came back at the end of its window (session metadata)
    back = {"depth": 1.8, "camera": 3.0, "range": 3.7, "imu": 4.4}
    for f in faults:
        rec = [e for e in events if e["event"] == "recovered" and e["kind"] == f["kind"]]
        assert rec, f
        assert rec[0]["t_s"] - back[f["kind"]] <= 1.0
    # while a fault is shown, the frame is the last good one plus the mark
    frames = s["frames"]
    for i, fr in enumerate(frames):
        if fr["kind"] == "status" and fr["faults"]:
            before = frames[i - 1]
            assert np.allclose(fr["mean_bgr"], before["mean_bgr"], atol=0.5)
    assert s["states"][-1][1] == "projecting"


def test_replay_command_writes_frames_summary_and_contact_sheet(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["replay", str(session_paths()["sphere"]), "--out", str(out), "--no-score"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counters"]["frames_shown"] == len(summary["frames"])
    assert {"surface", "content_free", "content_aware", "map", "render"} <= set(
        summary["timings_ms"]
    )
    assert (out / "contact_sheet.png").stat().st_size > 1000
    assert len(list((out / "frames").glob("sample_*.png"))) == len(summary["frames"])


def test_replay_of_a_missing_session_is_a_one_line_error(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["replay", "/nonexistent/x.mcap"]) == 2
    assert "not found" in capsys.readouterr().err
