"""``--compensate`` / ``--no-compensate`` where frames are made (``adaproj warp`` and
``adaproj simulate``): off by default (the frame as before, bit for bit), on it only
dims (the gain is at most 1) and the report carries the photometric figures."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.content.builtin import poster
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.projector import Projector


@pytest.fixture
def files(tmp_path: Path) -> Path:
    """Small surfaces (a 320x200 projector: the commands run at the file's size)."""
    small = Projector.default(320, 200)
    for name in ("tilted", "corner"):
        simulate_surface(name, small).save(tmp_path / f"{name}.npz")
    return tmp_path


def _warp(tmp: Path, name: str, *flags: str) -> np.ndarray:
    frame = tmp / f"{name}.png"
    argv = [
        "warp", "--surface", str(tmp / "tilted.npz"), "--image", str(tmp / "img.png"),
        "--mode", "conformal", "--out", str(tmp / f"{name}.npz"), "--frame", str(frame), *flags,
    ]  # fmt: skip
    assert main(argv) == 0
    return np.asarray(cv2.imread(str(frame)))


def test_warp_compensates_only_when_asked(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cv2.imwrite(str(files / "img.png"), np.full((200, 320, 3), 128, np.uint8))
    plain = _warp(files, "default")
    plain_report = json.loads(capsys.readouterr().out)
    off = _warp(files, "off", "--no-compensate")
    capsys.readouterr()
    on = _warp(files, "on", "--compensate")
    report = json.loads(capsys.readouterr().out)
    assert "photometry" not in plain_report
    assert np.array_equal(plain, off)  # the default is off: the same code path
    assert np.all(on <= plain)  # a gain of at most 1
    lit = plain > 0
    assert np.count_nonzero(on[lit] < plain[lit]) > 0.5 * np.count_nonzero(lit)
    figures = report["photometry"]
    # a wall at 35 degrees: its light falls ~2.7x over the picture; the budget keeps
    # 70 % of the brightness, so it is evened out only in part, and says so
    assert figures["ratio_before"] > 2.0
    assert figures["ratio_after"] < figures["ratio_before"]
    assert figures["mean_ratio"] >= 0.7 - 1e-6


def test_simulate_with_compensate_writes_the_picture(tmp_path: Path) -> None:
    out = tmp_path / "sim.png"
    cv2.imwrite(str(tmp_path / "img.png"), poster((320, 200)))
    argv = ["simulate", "--surface", "corner", "--grid", "12x8", "--mode", "conformal"]
    assert (
        main([*argv, "--image", str(tmp_path / "img.png"), "--compensate", "--out", str(out)]) == 0
    )
    pic = cv2.imread(str(out))
    assert pic.shape[1] > 4 * pic.shape[0]  # input | standard | corrected | compensated


def test_simulate_on_a_coloured_surface_in_a_lit_room(
    files: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--albedo`` and ``--ambient``: the projections as seen on the surface's colour
    with the room's light; with ``--compensate`` the colour is measured from simulated
    captures and said so; bad input is one line and exit 2, before any work."""
    out = files / "sim.png"
    albedo = files / "albedo.png"
    tile = np.array([[[120, 170, 230], [60, 85, 115]]], np.uint8)  # tinted, contrast 0.5
    cv2.imwrite(str(albedo), np.tile(tile, (50, 40, 1)))
    argv = ["simulate", "--surface", str(files / "corner.npz"), "--grid", "12x8"]
    argv += ["--mode", "conformal", "--out", str(out)]
    assert main([*argv, "--albedo", str(albedo), "--ambient", "0.05", "--compensate"]) == 0
    said = capsys.readouterr().out
    assert "surface colour compensated" in said
    seen = cv2.imread(str(out))
    assert seen.shape[1] > 4 * seen.shape[0]  # input | standard | corrected | compensated
    for bad, why in [
        (["--albedo", str(files / "none.png")], "image not found"),
        (["--albedo", str(files / "corner.npz")], "image"),
        (["--ambient", "nan"], "ambient"),
        (["--ambient", "-0.1"], "ambient"),
    ]:
        assert _status([*argv, *bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert why in err[-1]


def _status(argv: list[str]) -> int:
    """The exit status of ``adaproj argv`` (argparse's own errors exit)."""
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code or 0)
