"""Board files, calibration files and clocks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.clock import MonotonicClock, VirtualClock


def test_reference_board_and_its_calibration() -> None:
    b = Board.load("rpi5-oakd")
    assert b.imu.address == 0x6A and b.imu.bus == 1 and b.key_code == 28
    assert b.serial_device == "/dev/ttyGS0" and b.depth.width == 640
    assert b.display.refresh_hz == 60.0 and b.display.stabilise_margin == 0.04
    assert b.imu.config.rate_hz >= 400 and b.imu.config.fifo
    c = b.calibration()
    assert c.projector.width == 1280 and c.T_P_D.shape == (4, 4)


def write_board(tmp_path: Path, extra: str) -> Path:
    p = tmp_path / "b.toml"
    p.write_text(
        'name = "x"\ncalibration = "c.toml"\n[imu]\nbus = 1\n'
        '[button]\ndevice = "/dev/input/event0"\nkey_code = 28\n' + extra
    )
    return p


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        ("[depth]\nfoo = 1\n", "unknown keys"),
        ("[depth]\nmedian = 'x'\n", "median"),
        ("[display]\nstabilise_margin = 0.5\n", "stabilise_margin"),
        ("[display]\nrefresh_hz = 0\n", "refresh_hz"),
        ("[display]\nvsync = true\n", "unknown keys"),
    ],
)
def test_bad_board_files(tmp_path: Path, extra: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        Board.load(write_board(tmp_path, extra))


def test_bad_imu_address(tmp_path: Path) -> None:
    p = write_board(tmp_path, "")
    p.write_text(p.read_text().replace("bus = 1", "bus = 1\naddress = 0x68"))
    with pytest.raises(InputError, match="0x68"):
        Board.load(p)


def test_missing_board() -> None:
    with pytest.raises(InputError, match="not found"):
        Board.load("no-such-board")


def test_calibration_round_trip_and_errors(tmp_path: Path) -> None:
    c = Calibration.default()
    c2 = Calibration.from_json(c.to_json())
    assert np.array_equal(c2.T_P_D, c.T_P_D) and np.array_equal(c2.depth.K, c.depth.K)
    bad = c.to_dict()
    bad["extrinsics"]["R_P_I"] = [[2, 0, 0], [0, 1, 0], [0, 0, 1]]
    with pytest.raises(InputError, match="rotation"):
        Calibration.from_dict(bad)
    with pytest.raises(InputError, match="format"):
        Calibration.from_dict({})
    with pytest.raises(InputError, match="not found"):
        Calibration.load(tmp_path / "none.toml")
    (tmp_path / "x.toml").write_text("format = 'adaproj-calibration/1'\n")
    with pytest.raises(InputError, match="missing field"):
        Calibration.load(tmp_path / "x.toml")


def test_clocks() -> None:
    v = VirtualClock(10)
    v.advance_to(5)
    assert v.now_ns() == 10
    v.sleep_until(30)
    assert v.now_ns() == 30
    m = MonotonicClock()
    t = m.now_ns()
    m.sleep_until(t)
    assert m.now_ns() >= t
