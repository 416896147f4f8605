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


@pytest.mark.parametrize(
    ("extra", "key", "allowed"),
    [
        ("[depth]\nfps = nan\n", "[depth] fps", "(0, 120]"),
        ("[depth]\nwidth = -640\n", "[depth] width", "[16, 4096]"),
        ("[depth]\nwidth = 640.5\n", "[depth] width", "[16, 4096]"),
        ("[depth]\nsubpixel = 1\n", "[depth] subpixel", "true or false"),
        ("[depth]\npreset = 'FAST'\n", "[depth] preset", "DEFAULT"),
        ("[depth]\nleft_right_threshold = 1000\n", "[depth] left_right_threshold", "[0, 128]"),
        ("[display]\nrefresh_hz = nan\n", "[display] refresh_hz", "[1, 1000]"),
        ("[display]\nrefresh_hz = '60'\n", "[display] refresh_hz", "[1, 1000]"),
        ("[calibrate]\nfps = inf\n", "[calibrate] fps", "(0, 240]"),
        (
            "[calibrate]\ndisplay_latency_ms = -1.0\n",
            "[calibrate] display_latency_ms",
            "[0, 10000]",
        ),
        ("[calibrate]\niso = 400.5\n", "[calibrate] iso", "[100, 1600]"),
        ("[serial]\ndevice = 5\n", "[serial] device", "a string"),
        ("[serial]\nbaud = 5\n", "[serial] unknown keys", "device"),
        ("[depth]\nwidth = " + "[" * 3000 + "]" * 3000 + "\n", "nested too deeply", ""),
    ],
)
def test_every_board_field_is_checked(tmp_path: Path, extra: str, key: str, allowed: str) -> None:
    p = write_board(tmp_path, extra)
    with pytest.raises(InputError) as e:
        Board.load(p)
    message = str(e.value)
    assert str(p) in message and key in message and allowed in message, message


@pytest.mark.parametrize(
    ("old", "new", "key", "allowed"),
    [
        ("bus = 1", "bus = 99999999999999999", "[imu] bus", "[0, 1023]"),
        ("bus = 1", "bus = -1", "[imu] bus", "[0, 1023]"),
        ("bus = 1", "bus = true", "[imu] bus", "[0, 1023]"),
        ("key_code = 28", "key_code = 28.5", "[button] key_code", "[1, 767]"),
        ('name = "x"', "name = 5", "name", "a string"),
        ('name = "x"', 'name = "x"\ndepth = 5', "[depth] must be a table", ""),
        ('name = "x"', 'name = "x"\nextra = 5', "unknown keys ['extra']", ""),
    ],
)
def test_board_imu_and_button_fields_are_checked(
    tmp_path: Path, old: str, new: str, key: str, allowed: str
) -> None:
    p = write_board(tmp_path, "")
    p.write_text(p.read_text().replace(old, new))
    with pytest.raises(InputError) as e:
        Board.load(p)
    message = str(e.value)
    assert str(p) in message and key in message and allowed in message, message


@pytest.mark.parametrize(
    ("table", "field", "value", "key", "allowed"),
    [
        ("projector", "width", "1e9", "[projector] width", "[2, 16384]"),
        ("projector", "height", "0", "[projector] height", "[2, 16384]"),
        ("depth", "width", "-640", "[depth] width", "[2, 16384]"),
        ("depth", "baseline_m", "nan", "[depth] baseline_m", "(0, 1]"),
        ("depth", "baseline_m", "-0.075", "[depth] baseline_m", "(0, 1]"),
        ("depth", "baseline_m", "'wide'", "[depth] baseline_m", "(0, 1]"),
    ],
)
def test_every_calibration_field_is_checked(
    tmp_path: Path, table: str, field: str, value: str, key: str, allowed: str
) -> None:
    text = Calibration.default().to_toml()
    head, _, rest = text.partition(f"[{table}]\n")
    lines = [f"{field} = {value}" if ln.startswith(f"{field} =") else ln for ln in rest.split("\n")]
    p = tmp_path / "cal.toml"
    p.write_text(head + f"[{table}]\n" + "\n".join(lines))
    with pytest.raises(InputError) as e:
        Calibration.load(p)
    message = str(e.value)
    assert str(p) in message and key in message and allowed in message, message


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_deeply_nested_calibration_is_an_input_error(tmp_path: Path, suffix: str) -> None:
    p = tmp_path / f"cal{suffix}"
    nested = "[" * 100_000 + "]" * 100_000
    p.write_text(f"x = {nested}\n" if suffix == ".toml" else f'{{"x": {nested}}}')
    with pytest.raises(InputError, match="nested too deeply"):
        Calibration.load(p)
