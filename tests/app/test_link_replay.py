"""Serial traffic in a replay: a content push recorded mid-session goes through the
device's SMP server and switches the projected content at the same point."""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from adaproj_edge.app.replay import ReplayOptions, replay_session
from adaproj_edge.cli import main
from adaproj_edge.session.reader import Scan, iter_records, read_calibration
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.writer import SessionWriter
from tests.app.golden import PUSH_SESSION, push_meta

OPTIONS = ReplayOptions(score=False)


def _mean(frames: list[dict[str, Any]]) -> np.ndarray:
    return np.mean([f["mean_bgr"] for f in frames], axis=0)


@pytest.fixture(scope="module")
def pushed(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path]:
    out = tmp_path_factory.mktemp("push")
    return replay_session(PUSH_SESSION, out, OPTIONS), out


def _requests() -> list[SerialTraffic]:
    """The push's requests as recorded (one record each: the host's upload, its checks
    of the uploaded file and the activation, as ``adaproj push --activate`` sends them)."""
    return [
        r
        for r in iter_records(PUSH_SESSION)
        if isinstance(r, SerialTraffic) and r.direction == "rx"
    ]


def test_the_fixture_is_small_and_holds_a_push() -> None:
    assert PUSH_SESSION.stat().st_size < 1_000_000
    rx = _requests()
    assert len(rx) >= 4 and sum(len(r.data) for r in rx) > push_meta(PUSH_SESSION)["bytes"]


def test_a_recorded_push_switches_the_content_at_the_push(
    pushed: tuple[dict[str, Any], Path],
) -> None:
    s, _ = pushed
    push = push_meta(PUSH_SESSION)
    content = [e for e in s["events"] if e["event"] == "content"]
    assert len(content) == 1
    assert content[0]["item"] == push["name"] and content[0]["source"] == "link"
    t = content[0]["t_s"]
    assert push["t_s"] <= t < push["t_s"] + 0.2  # the upload takes ~70 ms on the line
    # the runtime re-renders for the new content at once, and keeps projecting
    assert any(u["t_s"] == t and u["reason"] == "new content" for u in s["updates"])
    assert s["states"][-1][1] == "projecting"
    link = s["link"]
    assert link["requests"] == link["replies"] == link["recorded_replies"] == len(_requests())
    assert link["content_activations"] == 1
    assert link["tx_mismatches"] == 0 and link["dropped_frames"] == {}
    # the client's probe of a file the device does not hold yet is a probe, not a refusal
    assert link["refused"] == 0


def test_the_frames_after_the_push_show_the_new_content(
    pushed: tuple[dict[str, Any], Path],
) -> None:
    s, _ = pushed
    t = next(e["t_s"] for e in s["events"] if e["event"] == "content")
    before = [f for f in s["frames"] if 0 < f["t_s"] < t]
    after = [f for f in s["frames"] if f["t_s"] >= t]
    assert len(before) >= 3 and len(after) >= 3
    assert np.abs(_mean(before) - _mean(after)).max() > 20


def test_the_pushed_file_lands_in_the_store_byte_exact(
    pushed: tuple[dict[str, Any], Path],
) -> None:
    _, out = pushed
    push = push_meta(PUSH_SESSION)
    data = (out / "store" / push["name"]).read_bytes()
    assert len(data) == push["bytes"]
    assert hashlib.sha256(data).hexdigest() == push["sha256"]


def _corrupted(path: Path, out: Path, seed: int) -> int:
    """``path`` rewritten to ``out`` with a few bytes of the upload and activate
    requests changed; returns how many bytes were changed."""
    rng = np.random.default_rng(seed)
    scan = Scan()
    records = list(iter_records(path, scan=scan))
    rx = [i for i, r in enumerate(records) if isinstance(r, SerialTraffic) and r.direction == "rx"]
    changed = 0
    for i in rx[3:]:
        rec = records[i]
        assert isinstance(rec, SerialTraffic)
        data = bytearray(rec.data)
        for pos in rng.choice(len(data), size=3, replace=False):
            data[pos] = (data[pos] + int(rng.integers(1, 256))) % 256
            changed += 1
        records[i] = SerialTraffic(rec.receive_ns, rec.direction, bytes(data))
    start = min(r.receive_ns for r in records)
    with SessionWriter(out, read_calibration(path), scan.metadata["session"], start) as w:
        for name, blob in scan.attachments.items():
            if name != "calibration.json":
                w.attach(name, "application/json", blob, start)
        for r in records:
            w.write(r)
    return changed


def test_corrupted_serial_bytes_are_logged_and_projection_goes_on(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    bad = tmp_path / "bad.mcap"
    assert _corrupted(PUSH_SESSION, bad, seed=3) >= 9
    with caplog.at_level(logging.WARNING, logger="adaproj_edge.link"):
        s = replay_session(bad, tmp_path / "out", OPTIONS)
    assert any("dropped" in r.getMessage() for r in caplog.records)
    link = s["link"]
    assert sum(link["dropped_frames"].values()) >= 1
    assert link["tx_mismatches"] >= 1  # the replies differ from the recorded ones
    # the push did not complete: no content switch, the poster stays, the device projects
    assert not [e for e in s["events"] if e["event"] == "content"]
    assert not (tmp_path / "out" / "store" / push_meta(PUSH_SESSION)["name"]).exists()
    assert s["states"][-1][1] == "projecting"
    assert s["frames"][-1]["t_s"] > push_meta(PUSH_SESSION)["t_s"] + 1.0


def test_the_replay_command_reports_the_link(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(PUSH_SESSION), "--out", str(tmp_path), "--no-score"]) == 0
    out = capsys.readouterr().out
    n = len(_requests())
    assert (
        f"serial link: {n} requests (0 refused, 0 bad frames dropped), 1 content activations" in out
    )
    assert "0 replies differ" in out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["link"]["content_activations"] == 1
    assert (tmp_path / "store" / push_meta(PUSH_SESSION)["name"]).exists()
