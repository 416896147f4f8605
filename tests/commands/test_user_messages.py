"""What a new user's mistakes get back: one line that says what is wrong and what would
work, each from the real command (``main``, in this process), never a traceback, a
silent default or a misleading word."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge import __version__
from adaproj_edge.cli import build_parser, main
from adaproj_edge.resources import boards_dir

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
NOMINAL = boards_dir().parent / "calibration" / "rpi5-oakd.toml"


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def usage_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


def test_replaying_a_calibration_session_says_how_to_solve_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = FIXTURES / "calibration" / "corner.mcap"
    assert main(["replay", str(session), "--out", str(tmp_path / "r")]) == 2
    line = error_line(capsys)
    assert "is a calibration session" in line
    assert line.endswith(f"solve it with `adaproj calibrate --replay {session}`")


@pytest.mark.parametrize("seconds", ["nan", "inf", "-1"])
def test_simulate_session_refuses_a_length_that_is_not_a_number_of_seconds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], seconds: str
) -> None:
    out = tmp_path / "s.mcap"
    argv = ["simulate-session", "--surface", "plane", "--seconds", seconds, "--out", str(out)]
    assert main(argv) == 2
    assert error_line(capsys).endswith(f"--seconds must be in (0, 600], got {float(seconds)}")
    assert not out.exists()


def test_simulate_refuses_a_viewer_that_is_not_a_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [
        "simulate",
        "--surface",
        "plane",
        "--viewer",
        "nan,0,0",
        "--out",
        str(tmp_path / "p.png"),
    ]
    assert "expected finite X,Y,Z in metres, got 'nan,0,0'" in usage_error(capsys, argv)


def test_calibrate_refuses_zero_poses(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", "--max-poses", "0"]) == 2
    assert error_line(capsys).endswith("--max-poses must be at least 1, got 0")


def test_calibrate_says_max_poses_does_not_apply_to_a_replay(
    capsys: pytest.CaptureFixture[str],
) -> None:
    session = FIXTURES / "calibration" / "corner.mcap"
    assert main(["calibrate", "--replay", str(session), "--max-poses", "3"]) == 2
    assert "a replay solves the poses its session recorded" in error_line(capsys)


@pytest.mark.parametrize("how", ["positional", "option"])
def test_device_screenshot_takes_its_file_either_way(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], how: str
) -> None:
    shot = str(tmp_path / "shot.png")
    where = [shot] if how == "positional" else ["--out", shot]
    port = str(tmp_path / "no-port")
    assert main(["device", "screenshot", *where, "--port", port]) == 2
    line = error_line(capsys)  # parsed: what fails is the missing device, not the usage
    assert line.startswith("adaproj device: error: serial port") and "is not there" in line


def test_device_screenshot_without_a_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["device", "screenshot", "--port", str(tmp_path / "p")]) == 2
    assert "give one PNG file to write" in error_line(capsys)


def test_replay_names_its_outputs_without_doubled_slashes_and_warns_once_of_damage(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes((FIXTURES / "app" / "push.mcap").read_bytes()[:150_000])
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING):
        assert main(["replay", str(cut), "--no-score", "--out", f"{out}/"]) == 0
    std = capsys.readouterr()
    wrote = [line for line in std.out.splitlines() if line.startswith("wrote ")]
    assert wrote == [f"wrote {out / 'summary.json'}, {out / 'contact_sheet.png'}, {out / 'frames'}"]
    assert "//" not in std.out
    said = [r for r in caplog.records if "cut short" in r.getMessage()]
    assert not said and std.err.count("cut short") == 1
    assert f"adaproj replay: warning: {cut.name}: the file is cut short" in std.err


def test_demo_and_replay_do_not_share_an_output_folder() -> None:
    demo = build_parser({"demo"}).parse_args(["demo"])
    assert demo.out == Path("out/demo")  # the README's replay writes out/summary.json


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"adaproj {__version__}"


def test_a_file_that_is_not_mcap_says_so_without_empty_brackets(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "s.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n")
    assert main(["replay", str(bad)]) == 2
    line = error_line(capsys)
    # the reason, when there is one, in brackets; never empty ones
    assert f"{bad} is not an MCAP session file" in line and "()" not in line, line


def test_a_calibration_with_a_nan_in_k_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = NOMINAL.read_text().replace("[[1792.0, 0.0, 639.5]", "[[nan, 0.0, 639.5]", 1)
    assert "nan" in text
    cal = tmp_path / "cal.toml"
    cal.write_text(text)
    assert main(["run", "--check", "--calibration", str(cal)]) == 2
    line = error_line(capsys)
    assert "projector intrinsics K hold a NaN or an infinite value" in line
    assert "(3, 3)" not in line


def test_a_ply_without_coordinates_says_which(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ply = tmp_path / "bad.ply"
    ply.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float a\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 1\n1 0 1\n0 1 1\n3 0 1 2\n"
    )
    argv = ["simulate-session", "--surface", str(ply), "--out", str(tmp_path / "s.mcap")]
    assert main(argv) == 2
    line = error_line(capsys)
    assert "is not in list" not in line
    assert line.endswith("is malformed: its vertices have no x (their properties: a, y, z)")


@pytest.mark.parametrize(
    ("grid", "message"),
    [
        ("0x0", "grid 0x0 has 0 triangles; the warp needs at least"),
        ("401x2", "grid 401x2 is too fine: at most 400x400 cells"),
    ],
)
def test_grid_messages_state_the_real_limits(
    capsys: pytest.CaptureFixture[str], grid: str, message: str
) -> None:
    argv = ["warp", "--surface", "plane", "--image", "i.png", "--out", "w", "--grid", grid]
    line = usage_error(capsys, argv)
    assert message in line and "outside 1x1" not in line


def test_a_content_map_is_called_a_content_map(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    image, cmap = tmp_path / "i.png", tmp_path / "c.png"
    cv2.imwrite(str(image), np.full((100, 160, 3), 128, np.uint8))
    cv2.imwrite(str(cmap), np.full((100, 100), 255, np.uint8))
    argv = ["warp", "--surface", "plane", "--image", str(image), "--content-map", str(cmap)]
    assert main([*argv, "--out", str(tmp_path / "w.npz")]) == 2
    line = error_line(capsys)
    assert "a content map must have the content's aspect ratio" in line and "mask" not in line


def test_a_truncated_clip_is_one_line_without_ffmpeg_noise(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    clip = tmp_path / "cut.mp4"
    clip.write_bytes((FIXTURES / "video" / "h264.mp4").read_bytes()[:4000])
    assert main(["push", str(clip), "--port", str(tmp_path / "p")]) == 2
    err = capfd.readouterr().err.strip().splitlines()  # the file descriptor: FFmpeg's too
    assert len(err) == 1, err
    assert err[0].startswith("adaproj push: error: ")
    assert err[0].endswith("frame 1 of 30 does not decode (truncated or corrupt file)")
