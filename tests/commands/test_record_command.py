"""``adaproj record`` without the board: each missing device is a one-line error."""

from __future__ import annotations

from pathlib import Path

import pytest

from adaproj_edge.cli import main

CAL = Path(__file__).resolve().parents[2] / "hw" / "calibration" / "rpi5-oakd.toml"


def board(tmp_path: Path, bus: int) -> Path:
    p = tmp_path / "b.toml"
    p.write_text(
        f'name = "test"\ncalibration = "{CAL}"\n[imu]\nbus = {bus}\n'
        f'[button]\ndevice = "{tmp_path}/event0"\nkey_code = 28\n'
    )
    return p


def test_missing_i2c_bus(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["record", "--board", str(board(tmp_path, 97)), "--out", str(tmp_path / "s.mcap")])
    assert rc == 2
    assert "/dev/i2c-97" in capsys.readouterr().err


def test_unknown_board(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["record", "--board", "nope", "--out", str(tmp_path / "s.mcap")]) == 2
    assert "board file not found" in capsys.readouterr().err
