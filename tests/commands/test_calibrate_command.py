"""``adaproj calibrate``, ``adaproj simulate-calibration``, and the calibration choices
of ``adaproj run`` and ``adaproj replay``, from the command line."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import pytest

from adaproj_edge.cli import main
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.session.reader import read_session
from tests.commands.test_record_command import board
from tests.procam.golden import FIXTURE


def test_calibrate_from_the_recorded_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "unit.toml"
    assert main(["calibrate", "--replay", str(FIXTURE), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "pose 2: move closer" in text and "acceptable: reprojection RMS" in text
    assert f"wrote {out}\n" in text and "unit.report.png" in text
    q = tomllib.loads(out.read_text())["quality"]
    assert q["verdict"] == "acceptable" and q["poses"] == 3
    # a better file is not replaced ...
    out.write_text(out.read_text().replace(f"rms_px = {q['rms_px']}", "rms_px = 0.05"))
    assert main(["calibrate", "--replay", str(FIXTURE), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds a better calibration" in err[0] and "--force" in err[0]
    assert tomllib.loads(out.read_text())["quality"]["rms_px"] == 0.05
    # ... unless forced
    assert main(["calibrate", "--replay", str(FIXTURE), "--out", str(out), "--force"]) == 0
    assert tomllib.loads(out.read_text())["quality"]["rms_px"] == q["rms_px"]


def test_replay_and_record_do_not_mix(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["calibrate", "--replay", str(FIXTURE), "--record", str(tmp_path / "s.mcap")]
    assert main([*args, "--out", str(tmp_path / "x.toml")]) == 2
    assert "cannot go with --replay" in capsys.readouterr().err


def test_not_a_calibration_session(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session = Path(__file__).resolve().parents[1] / "fixtures" / "sessions" / "sphere.mcap"
    assert main(["calibrate", "--replay", str(session), "--out", str(tmp_path / "x.toml")]) == 2
    assert "not a calibration session" in capsys.readouterr().err


def test_a_cut_session_stops_with_a_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(FIXTURE.read_bytes()[: FIXTURE.stat().st_size // 2])
    assert main(["calibrate", "--replay", str(cut), "--out", str(tmp_path / "x.toml")]) == 2
    err = capsys.readouterr().err
    assert "recording ended" in err or "ends before" in err
    assert not (tmp_path / "x.toml").exists()


def test_calibrate_on_a_board_without_devices(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(["calibrate", "--board", str(board(tmp_path, 97)), "--out", str(tmp_path / "x.toml")])
    assert rc == 2 and "/dev/i2c-97" in capsys.readouterr().err


def test_simulate_calibration_with_the_projector_off(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = tmp_path / "rig.toml"
    rig.write_text(Calibration.default().to_toml())
    out = tmp_path / "s.mcap"
    args = ["simulate-calibration", "--surface", "corner", "--rig", str(rig), "--poses", "2"]
    args += ["--camera", "96x60", "--fault", "projector-off", "--out", str(out)]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "nothing decodes" in text and "wrote" in text
    s = read_session(out)
    assert s.metadata["session"]["kind"] == "calibration" and len(s.depth) == 3
    assert main([*args, "--camera", "big"]) == 2
    assert "WIDTHxHEIGHT" in capsys.readouterr().err


def test_run_refuses_a_bad_calibration_file_before_the_devices(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("format = 'adaproj-calibration/1'\n")
    assert main(["run", "--calibration", str(bad)]) == 2
    assert "missing field" in capsys.readouterr().err


def test_replay_with_another_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = Path(__file__).resolve().parents[1] / "fixtures" / "sessions" / "sphere.mcap"
    assert main(["replay", str(session), "--calibration", str(tmp_path / "none.toml")]) == 2
    assert "calibration file not found" in capsys.readouterr().err
    mine = tmp_path / "mine.toml"
    shutil.copy(Path(__file__).resolve().parents[2] / "hw/calibration/rpi5-oakd.toml", mine)
    mine.write_text(mine.read_text().replace("1792.0, 0.0, 639.5", "1700.0, 0.0, 639.5"))
    assert main(["replay", str(session), "--calibration", str(mine), "--no-score"]) == 0
