"""The README's first quick-start command: replay the built-in recording."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from adaproj_edge.cli import main


@pytest.mark.slow
def test_replay_without_arguments_replays_the_built_in_recording(tmp_path: Path) -> None:
    assert main(["replay", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["session"].endswith("cylinder.mcap")
    assert summary["counters"]["frames_shown"] > 0
    assert (tmp_path / "contact_sheet.png").stat().st_size > 0
