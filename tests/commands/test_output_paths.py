"""Outputs that cannot be written end a command with one line and exit 2, before any
work; images are encoded as their names say; files are made as the umask says; a reader
that goes away (``| head``) is no traceback (issue 12, item 6)."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from adaproj_edge import fileio
from adaproj_edge.cli import main
from adaproj_edge.content.builtin import poster
from adaproj_edge.render import project as project_module

UNWRITABLE = "/proc/adaproj-test/out"  # no one can create files in /proc, root included


@pytest.fixture
def image(tmp_path: Path) -> Path:
    path = tmp_path / "img.png"
    cv2.imwrite(str(path), poster((160, 100)))
    return path


@pytest.fixture
def no_work(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """Fails the test if a warp is computed: every check must come before the work."""
    calls: list[str] = []

    def refuse(*args: Any, **kwargs: Any) -> None:
        calls.append("project")
        raise AssertionError("the warp was computed before the outputs were checked")

    monkeypatch.setattr(project_module, "project", refuse)
    yield calls
    assert calls == []


def one_error_line(capsys: pytest.CaptureFixture[str], command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"adaproj {command}: error: ")
    return err[0]


def warp_argv(image: Path, out: str, *extra: str) -> list[str]:
    return ["warp", "--surface", "plane", "--image", str(image), "--out", out, *extra]


@pytest.mark.parametrize(
    ("out", "frame", "message"),
    [
        ("{d}", None, "is a folder"),
        (UNWRITABLE + "/w.npz", None, "cannot create files in /proc"),
        ("{d}/w.npz", "{d}", "frame {d} is a folder"),
        ("{d}/w.npz", "{d}/f.gif", "must end in .png, .jpg or .jpeg"),
        ("{d}/w.npz", "{d}/f", "must end in .png, .jpg or .jpeg"),
        ("{d}/w.npz", UNWRITABLE + "/f.png", "cannot create files in /proc"),
        ("{d}/file/w.npz", None, "is not a folder"),
    ],
)
def test_warp_outputs_are_checked_before_any_work(
    tmp_path: Path,
    image: Path,
    no_work: list[str],
    capsys: pytest.CaptureFixture[str],
    out: str,
    frame: str | None,
    message: str,
) -> None:
    (tmp_path / "file").write_text("a file where a folder is wanted")
    extra = [] if frame is None else ["--frame", frame.format(d=tmp_path)]
    assert main(warp_argv(image, out.format(d=tmp_path), *extra)) == 2
    assert message.format(d=tmp_path) in one_error_line(capsys, "warp")
    assert not (tmp_path / "w.npz").exists()


def test_replay_out_that_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "summary"
    out.write_text("not a folder")
    assert main(["replay", "--out", str(out)]) == 2
    assert "is a file, not a folder" in one_error_line(capsys, "replay")


@pytest.mark.parametrize(
    ("surfaces", "message"),
    [
        ("", "no surface named; choose from plane, "),
        (" , ", "no surface named"),
        ("corner,donut", "unknown surface donut; built-in surfaces: plane, "),
        ("donut,corner,ring", "unknown surfaces donut, ring"),
    ],
)
def test_demo_checks_every_surface_before_computing_any(
    tmp_path: Path,
    no_work: list[str],
    capsys: pytest.CaptureFixture[str],
    surfaces: str,
    message: str,
) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--surfaces", surfaces]) == 2
    assert message in one_error_line(capsys, "demo")
    assert not out.exists()  # no partial set


def test_demo_out_that_is_a_file(
    tmp_path: Path, no_work: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "f").write_text("")
    assert main(["demo", "--out", str(tmp_path / "f"), "--surfaces", "corner"]) == 2
    assert "is a file, not a folder" in one_error_line(capsys, "demo")


def test_other_outputs_are_checked_first(
    tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = str(tmp_path)
    cases = [
        (["simulate", "--surface", "corner", "--out", d], "simulate", "is a folder"),
        (["simulate", "--surface", "corner", "--out", d + "/p.bmp"], "simulate", "must end in"),
        (["surface", "plane", "--out", d], "surface", "is a folder"),
        (["saliency", str(image), "--out", d + "/m.tif"], "saliency", "must end in"),
        (["saliency", str(image), "--out", UNWRITABLE + "/m.png"], "saliency", "/proc"),
        (["simulate-session", "--surface", "plane", "--out", d], "simulate-session", "folder"),
        (["run", "--store", d + "/img.png", "--state", d], "run", "is a file, not a folder"),
    ]
    for argv, command, message in cases:
        assert main(argv) == 2, argv
        assert message in one_error_line(capsys, command), argv


def test_an_os_error_inside_a_command_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `adaproj link --store FILE`: the store's folder cannot be made where a file is
    store = tmp_path / "store"
    store.write_text("a file")
    r, w = os.pipe()
    try:
        assert main(["link", "--store", str(store), "--fd", str(r)]) == 2
    finally:
        os.close(r)
        os.close(w)
    line = one_error_line(capsys, "link")
    assert str(store) in line and "Traceback" not in line


@pytest.mark.parametrize(("name", "magic"), [("f.jpg", b"\xff\xd8"), ("f.JPEG", b"\xff\xd8")])
def test_frame_is_encoded_as_its_name_says(
    tmp_path: Path, image: Path, name: str, magic: bytes
) -> None:
    frame = tmp_path / name
    argv = warp_argv(image, str(tmp_path / "w.npz"), "--mode", "conformal", "--grid", "4x4")
    assert main([*argv, "--frame", str(frame)]) == 0
    data = frame.read_bytes()
    assert data.startswith(magic)
    assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR).shape == (800, 1280, 3)


def test_write_image_refuses_an_unknown_extension(tmp_path: Path) -> None:
    with pytest.raises(fileio.ImageError, match="cannot tell the image format"):
        fileio.write_image(tmp_path / "x.gif", np.zeros((4, 4), np.uint8))
    assert list(tmp_path.iterdir()) == []
    fileio.write_image(tmp_path / "x.png", np.zeros((4, 4), np.uint8))
    assert (tmp_path / "x.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_outputs_are_made_as_the_umask_says(tmp_path: Path, mask: int) -> None:
    old = os.umask(mask)
    try:
        assert main(["surface", "plane", "--step", "100", "--out", str(tmp_path / "s.npz")]) == 0
        fileio.atomic_write_bytes(tmp_path / "b.bin", b"x")
    finally:
        os.umask(old)
    for name in ("s.npz", "b.bin"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o666 & ~mask, name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bin", "s.npz"]  # no temp left


def test_a_reader_that_goes_away_is_no_traceback(tmp_path: Path, image: Path) -> None:
    argv = warp_argv(image, str(tmp_path / "w.npz"), "--mode", "conformal", "--grid", "4x4")
    with subprocess.Popen(
        [sys.executable, "-m", "adaproj_edge", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=tmp_path,
    ) as proc:
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.close()  # as `| head` does once it has what it wants
        err = proc.stderr.read().decode()
        rc = proc.wait(timeout=600)
    assert rc == 141, err  # 128 + SIGPIPE, as a shell reports it
    assert err == ""
    assert (tmp_path / "w.npz").stat().st_size > 0  # the work was kept
