"""``adaproj saliency``."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.content.overlay import FACE_COLOUR
from tests.content.displays import colour_popout
from tests.content.facescenes import astronaut, region_ratio


@pytest.fixture
def image_file(tmp_path: Path) -> Path:
    img, _, _ = colour_popout(8)
    path = tmp_path / "in.png"
    cv2.imwrite(str(path), cv2.resize(img, (640, 400)))
    return path


def test_writes_the_map_and_the_overlay(
    image_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mask = np.zeros((40, 64), np.uint8)
    mask[30:, :10] = 255
    cv2.imwrite(str(tmp_path / "m.png"), mask)
    out, over = tmp_path / "map.png", tmp_path / "over.png"
    args = ["saliency", str(image_file), "--out", str(out), "--overlay", str(over)]
    assert main([*args, "--mask", str(tmp_path / "m.png")]) == 0
    cmap = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    assert cmap.shape == (400, 640) and cmap.dtype == np.uint8
    assert cmap.max() == 255 and cmap[390, 5] == 255  # the masked corner
    assert cv2.imread(str(over)).shape == (400, 640, 3)
    assert "salient" in capsys.readouterr().out


def test_a_bad_mask_is_a_clear_error(
    image_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "bad.png").write_bytes(b"not a png")
    rc = main(
        [
            "saliency",
            str(image_file),
            "--out",
            str(tmp_path / "o.png"),
            "--mask",
            str(tmp_path / "bad.png"),
        ]
    )
    assert rc == 2
    err = capsys.readouterr().err
    assert "adaproj saliency: error: mask rejected" in err and "bad.png" in err
    assert not (tmp_path / "o.png").exists()


def test_a_missing_model_is_a_clear_error(
    image_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(
        [
            "saliency",
            str(image_file),
            "--out",
            str(tmp_path / "o.png"),
            "--model",
            str(tmp_path / "none.onnx"),
        ]
    )
    assert rc == 2
    assert "saliency model not found" in capsys.readouterr().err


def test_faces_are_in_the_map_and_drawn_in_the_overlay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = astronaut()
    assert scene.face is not None
    src = tmp_path / "astronaut.png"
    cv2.imwrite(str(src), scene.image)
    out, over = tmp_path / "map.png", tmp_path / "over.png"
    assert main(["saliency", str(src), "--out", str(out), "--overlay", str(over)]) == 0
    assert "1 face(s)" in capsys.readouterr().out
    x, y, w, h = scene.face
    cmap = cv2.imread(str(out), cv2.IMREAD_UNCHANGED).astype(np.float64) / 255.0
    assert region_ratio(cmap, scene.face) >= 1.5
    magenta = np.all(cv2.imread(str(over)) == FACE_COLOUR, axis=2)
    ys, xs = np.nonzero(magenta)
    assert len(xs) > 100 and x < xs.mean() < x + w and y < ys.mean() < y + h
    plain = tmp_path / "plain.png"
    assert main(["saliency", str(src), "--out", str(plain), "--no-faces"]) == 0
    assert "face(s)" not in capsys.readouterr().out
    values = cv2.imread(str(plain), cv2.IMREAD_UNCHANGED).astype(np.float64) / 255.0
    assert region_ratio(values, scene.face) < 1.0
