"""What a newcomer reads: errors that say what would work, ``--help`` that describes every
command and comes quickly (issue 12, item 7)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

from adaproj_edge import commands
from adaproj_edge.cli import build_parser, main
from adaproj_edge.content.builtin import poster
from adaproj_edge.geometry.analytic import SURFACES
from adaproj_edge.resources import boards_dir

HEAVY = ("numpy", "cv2", "scipy", "onnxruntime")
LIGHT_MODULES = [m for m in commands.MODULES if m not in ("link", "push", "device")]
"""The serial link's commands (link, push, device) are not yet light at import."""


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.fixture
def image(tmp_path: Path) -> Path:
    path = tmp_path / "img.png"
    cv2.imwrite(str(path), poster((160, 100)))
    return path


def test_unknown_surface_lists_the_built_in_ones(
    tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["warp", "--surface", "donut", "--image", str(image), "--out", str(tmp_path / "w")]
    assert main(argv) == 2
    line = error_line(capsys)
    assert "'donut' is neither a file nor a built-in surface" in line
    assert all(name in line for name in SURFACES)


def test_unknown_board_lists_the_boards(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--board", "nope", "--check"]) == 2
    line = error_line(capsys)
    boards = sorted(p.stem for p in boards_dir().glob("*.toml"))
    assert boards and "board file not found" in line
    assert all(b in line for b in boards)


@pytest.mark.parametrize(
    ("content", "name"),
    [(b"points = 1\n", "s.txt"), (b"", "empty.npz"), (b"\x93NUMPY\x01\x00", "a.npy")],
)
def test_a_file_that_is_not_an_npz_says_so(
    tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str], content: bytes, name: str
) -> None:
    (tmp_path / name).write_bytes(content)
    argv = ["warp", "--surface", str(tmp_path / name), "--image", str(image)]
    assert main([*argv, "--out", str(tmp_path / "w.npz")]) == 2
    line = error_line(capsys)
    assert "allow_pickle" not in line
    assert "is empty" in line or "not an .npz file (numpy's zip of arrays)" in line


@pytest.mark.parametrize("grid", ["1x1", "1x3", "3x1"])
def test_a_grid_too_coarse_for_any_warp_is_refused_when_parsed(
    grid: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # the image does not exist: the grid is refused before anything is read
    with pytest.raises(SystemExit) as e:
        main(["warp", "--surface", "plane", "--image", "nope.png", "--out", "w", "--grid", grid])
    assert e.value.code == 2
    assert "triangles; the warp needs at least" in capsys.readouterr().err


def test_the_smallest_grid_accepted_makes_a_warp(tmp_path: Path, image: Path) -> None:
    argv = ["warp", "--surface", "plane", "--image", str(image), "--mode", "conformal"]
    assert main([*argv, "--grid", "2x2", "--out", str(tmp_path / "w.npz")]) == 0


@pytest.mark.parametrize("step", [5000, 800, 0, -3])
def test_surface_step_out_of_range_is_one_clear_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], step: int
) -> None:
    assert main(["surface", "plane", "--step", str(step), "--out", str(tmp_path / "s.npz")]) == 2
    want = f"--step must be between 1 and 799 (the frame is 1280x800 pixels), got {step}"
    assert error_line(capsys).endswith(want)
    assert not (tmp_path / "s.npz").exists()


def test_the_largest_surface_step_gives_two_by_two_points(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["surface", "plane", "--step", "799", "--out", str(tmp_path / "s.npz")]) == 0
    assert "2x2 points" in capsys.readouterr().out


def test_every_command_has_a_description_and_a_summary() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices and "warp" in a.choices)
    assert sub.choices is not None
    for module in commands.MODULES:
        name = commands.command_name(module)
        assert commands.summary(module), module
        p = sub.choices[name]
        assert p.description and len(p.description) > 40, name


def test_help_lists_every_command_with_its_summary(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    for module in commands.MODULES:
        assert f"{commands.command_name(module)} {commands.summary(module)}" in out


def loaded_after(code: str) -> list[str]:
    """Heavy modules loaded by ``code`` in a fresh interpreter."""
    probe = (
        f"import sys, json\n{code}\nprint(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    ).stdout
    return list(json.loads(out.strip().splitlines()[-1]))


def test_help_loads_no_numeric_library() -> None:
    code = (
        "from adaproj_edge.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit as e:\n    assert e.code == 0\n"
    )
    assert loaded_after(code) == []


def test_command_modules_load_no_numeric_library_on_import() -> None:
    code = "\n".join(f"import adaproj_edge.commands.{m}" for m in LIGHT_MODULES)
    assert loaded_after(code) == []


def test_an_unknown_command_lists_the_commands(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["wrap"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'wrap'" in err and "warp" in err and "replay" in err


def test_the_selected_command_gets_its_full_parser(tmp_path: Path) -> None:
    parser = build_parser({"surface"})
    args = parser.parse_args(["surface", "bowl", "--out", str(tmp_path / "s.npz")])
    assert args.name == "bowl" and callable(args.run)
    with pytest.raises(SystemExit):
        parser.parse_args(["warp", "--surface", "plane"])  # only listed, not built


def test_summary_reads_the_docstring() -> None:
    assert commands.summary("warp") == "the pre-warp for one image on one surface"
    assert commands.summary("simulate_session") == "a recorded session from a virtual device"
