"""What a replay tells about its input and shows of the projection: damaged files are
named and flagged, an --out folder reused holds only this replay's outputs, the
distortion comes with its baseline and units, and the contact sheet shows a few moments
from the side."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.app.replay import ReplayOptions, replay_session
from adaproj_edge.app.report import SAMPLE_FRAMES, FrameSampler
from adaproj_edge.cli import main
from adaproj_edge.session.reader import Scan, iter_records
from tests.app.golden import session_paths


def _damaged(tmp_path: Path, how: str) -> Path:
    data = session_paths()["sphere"].read_bytes()
    path = tmp_path / f"{how}.mcap"
    if how == "cut":
        path.write_bytes(data[: len(data) // 2])
    else:
        path.write_bytes(data + bytes(range(256)) * 8)
    return path


def test_the_reader_names_a_cut_file_and_appended_bytes(tmp_path: Path) -> None:
    for how in ("cut", "garbage"):
        scan = Scan()
        n = sum(1 for _ in iter_records(_damaged(tmp_path, how), scan=scan))
        report = scan.report()
        assert n > 0 and report["damage"] is not None
        if how == "cut":
            assert report["truncated"] and not report["complete"]
            assert "cut short" in report["damage"]
        else:
            assert report["complete"] and report["trailing_bytes"] == 256 * 8
    clean = Scan()
    for _ in iter_records(session_paths()["sphere"], scan=clean):
        pass
    assert clean.damage() is None and clean.report()["trailing_bytes"] == 0


@pytest.mark.parametrize("how", ["cut", "garbage"])
def test_a_damaged_session_replays_with_a_warning_and_a_flag(
    tmp_path: Path, how: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    (out / "frames").mkdir(parents=True)
    (out / "frames" / "sample_99999_099.000s.png").write_bytes(b"stale")
    (out / "contact_sheet.png").write_bytes(b"stale")
    path = _damaged(tmp_path, how)
    assert main(["replay", str(path), "--out", str(out), "--no-score"]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and path.name in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["session_file"]["damage"] is not None
    assert summary["session_file"]["truncated"] == (how == "cut")
    # only this replay's outputs: the stale frame is gone, the sheet is a picture
    names = {p.name for p in (out / "frames").iterdir()}
    assert "sample_99999_099.000s.png" not in names
    assert len(names) == len(summary["frames"])
    assert cv2.imread(str(out / "contact_sheet.png")) is not None


def test_distortion_has_a_plain_projector_baseline_units_and_side_views(tmp_path: Path) -> None:
    path = session_paths()["cylinder"]
    with_views = replay_session(path, tmp_path / "a", ReplayOptions())
    measures = with_views["distortion_measures"]
    assert {"angle_error", "size_inconsistency", "plain_*"} <= set(measures)
    scores = with_views["distortion"]
    assert scores
    for d in scores:
        # a plain projector on a convex column shears the content; the device does not
        assert d["plain_angle_error"] > 2 * d["shown_angle_error"], d
        assert d["plain_salient_size_inconsistency"] >= 0.0
    replay_session(path, tmp_path / "b", ReplayOptions(side_views=False))
    sheet_a = cv2.imread(str(tmp_path / "a" / "contact_sheet.png"))
    sheet_b = cv2.imread(str(tmp_path / "b" / "contact_sheet.png"))
    # the side views are rows of their own under the frames
    assert sheet_a.shape[0] >= sheet_b.shape[0] + 2 * 300


def test_frames_are_sampled_only_for_an_output_folder(tmp_path: Path) -> None:
    """Without outputs the sampler keeps the checksums alone (no PNGs held in memory);
    with them, a bounded sample for the contact sheet."""
    frame = np.full((48, 64, 3), 90, np.uint8)
    info = {"faults": [], "kind": "content-free"}
    bare, kept = FrameSampler(None, False), FrameSampler(tmp_path, False)
    for k in range(5 * SAMPLE_FRAMES):
        bare(k * 1000, frame, info)
        kept(k * 1000, frame, info)
    assert len(bare.checksums) == len(kept.checksums) == 5 * SAMPLE_FRAMES
    assert bare.sample == []
    assert 0 < len(kept.sample) <= 2 * SAMPLE_FRAMES
