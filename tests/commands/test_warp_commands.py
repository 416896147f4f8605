"""``adaproj warp`` / ``surface`` / ``simulate`` / ``demo``: outputs, and one clear message
with a non-zero exit for every kind of bad input."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.content.builtin import poster
from adaproj_edge.warp.warpmap import Warp


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("cli")
    assert main(["surface", "sphere-concave", "--step", "4", "--out", str(d / "s.npz")]) == 0
    cv2.imwrite(str(d / "img.png"), poster((320, 200)))
    mask = np.zeros((100, 160), np.uint8)
    mask[30:70, 30:70] = 255
    cv2.imwrite(str(d / "mask.png"), mask)
    return d


def test_warp_writes_the_warp_and_the_frame(
    files: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(
        [
            "warp", "--surface", str(files / "s.npz"), "--image", str(files / "img.png"),
            "--mask", str(files / "mask.png"), "--grid", "16x10",
            "--out", str(files / "w.npz"), "--frame", str(files / "f.png"),
        ]
    )  # fmt: skip
    assert rc == 0
    warp = Warp.load(files / "w.npz")
    assert warp.map_xy is not None and warp.meta["mode"] == "content"
    frame = cv2.imread(str(files / "f.png"))
    assert frame.shape == (800, 1280, 3) and frame.max() > 0
    assert '"distortion_salient"' in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--surface", "nope.npz"], "neither a file nor a built-in surface"),
        (["--image", "nope.png"], "image not found"),
        (["--image", "{d}/s.npz"], "not a readable image"),
        (["--mask", "{d}/tall.png"], "aspect"),
        (["--surface", "{d}/few.npz"], "meets the surface"),
        (["--mode", "content", "--content-map", "nope.png"], "image not found"),
    ],
)
def test_bad_input_is_one_message_and_exit_2(
    files: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    cv2.imwrite(str(files / "tall.png"), np.zeros((300, 20), np.uint8))
    pts = np.full((20, 32, 3), np.nan, np.float32)
    pts[0, 0] = [0, 0, 1]
    np.savez(files / "few.npz", points=pts, K=np.array([[40.0, 0, 15.5], [0, 40, 9.5], [0, 0, 1]]))
    base = {
        "--surface": str(files / "s.npz"),
        "--image": str(files / "img.png"),
        "--out": str(files / "bad.npz"),
    }
    for k, v in zip(args[::2], args[1::2], strict=True):
        base[k] = v.format(d=files)
    argv = ["warp"] + [x for kv in base.items() for x in kv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("adaproj warp: error:") and message in err[0]
    assert "Traceback" not in err[0]
    assert not (files / "bad.npz").exists()


def test_bad_grid_is_a_usage_error(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["warp", "--surface", "plane", "--image", "x", "--out", "y", "--grid", "20by20"])
    assert e.value.code == 2
    assert "grid must look like" in capsys.readouterr().err


def test_simulate_writes_the_side_by_side_picture(files: Path) -> None:
    out = files / "sim.png"
    assert main(["simulate", "--surface", "corner", "--grid", "12x8", "--out", str(out)]) == 0
    pic = cv2.imread(str(out))
    assert pic.shape[1] > 3 * pic.shape[0]  # input | standard | corrected


@pytest.mark.slow
def test_demo_writes_pictures_and_a_summary(tmp_path: Path) -> None:
    assert main(["demo", "--out", str(tmp_path), "--surfaces", "cylinder-convex"]) == 0
    for name in ("demo.png", "input.png", "summary.json", "cylinder-convex.png"):
        assert (tmp_path / name).stat().st_size > 0
