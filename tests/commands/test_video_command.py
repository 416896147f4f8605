"""``adaproj video``: the real command on a small clip (frames.json as the issue asks, the
projected video, the side view), and one line with exit 2 for every kind of bad clip."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.geometry.analytic import simulate_surface
from tests.content.clips import write_clip

FRAMES = 8
MEASURES = {"angle", "size", "salient_angle", "salient_size"}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("video")
    clip = write_clip(d / "clip.avi", "MJPG", n=FRAMES, size=(160, 96), fps=20.0)
    mask = np.zeros((48, 80), np.uint8)
    mask[10:30, 10:40] = 255
    cv2.imwrite(str(d / "mask.png"), mask)
    rc = main(
        [
            "video", str(clip), "--surface", "sphere-concave", "--mask", str(d / "mask.png"),
            "--grid", "12x8", "--side-frames", "3", "--out", str(d / "out"),
        ]
    )  # fmt: skip
    assert rc == 0
    return d / "out"


def test_frames_json_has_one_object_per_frame_as_specified(rendered: Path) -> None:
    records = json.loads((rendered / "frames.json").read_text())
    assert len(records) == FRAMES
    for i, r in enumerate(records):
        assert set(r) == {
            "t", "image_xy", "iterations", "stage_ms", "distortion", "content_free_distortion"
        }  # fmt: skip
        assert r["t"] == pytest.approx(i / 20.0)
        xy = r["image_xy"]
        assert len(xy) == 9 and all(len(row) == 13 for row in xy)  # 8x12 cells
        vertices = [v for row in xy for v in row if v is not None]
        assert vertices and all(len(v) == 2 for v in vertices)
        # content pixels: vertices beyond the content's edges map outside it
        assert all(-160 < v[0] < 320 and -96 < v[1] < 192 for v in vertices)
        assert r["iterations"] >= 0  # 0: held (the content map did not move)
        assert set(r["stage_ms"]) == {"decode", "content", "refine", "maps", "render"}
        assert all(ms >= 0 for ms in r["stage_ms"].values())
        for key in ("distortion", "content_free_distortion"):
            assert set(r[key]) == MEASURES
            assert r[key]["angle"] >= 0 and r[key]["size"] >= 0
    # the first frame is solved cold, the later ones take the bounded warm steps (2)
    assert records[0]["iterations"] > 2
    assert all(r["iterations"] <= 2 for r in records[1:])
    # the same content-free warp measured on every frame over the whole content
    free = {r["content_free_distortion"]["size"] for r in records}
    assert len(free) == 1


def test_the_warp_is_content_aware_and_moves_smoothly(rendered: Path) -> None:
    records = json.loads((rendered / "frames.json").read_text())
    last = records[-1]
    assert last["distortion"]["salient_size"] < last["content_free_distortion"]["salient_size"]
    xy = np.array([[[np.nan] * 2 if v is None else v for v in row] for row in last["image_xy"]])
    prev = records[-2]["image_xy"]
    before = np.array([[[np.nan] * 2 if v is None else v for v in row] for row in prev])
    assert np.nanmax(np.abs(xy - before)) < 5.0  # no jump between frames


def test_the_projected_video_and_the_side_view(rendered: Path) -> None:
    cap = cv2.VideoCapture(str(rendered / "projected.avi"))
    p = simulate_surface("sphere-concave").projector
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    assert len(frames) == FRAMES and frames[0].shape == (p.height, p.width, 3)
    assert all(f.max() > 0 for f in frames)
    side = cv2.imread(str(rendered / "side.png"))
    assert side is not None and side.shape[1] > side.shape[0]
    assert not list(rendered.glob(".*part*"))  # nothing half-written left behind


def _bad_clips(d: Path) -> dict[str, tuple[Path, str]]:
    good = write_clip(d / "good.avi", "MJPG", n=10)
    data = good.read_bytes()
    (d / "cut.avi").write_bytes(data[: len(data) // 3])
    junk = bytearray(data)
    junk[200:] = np.random.default_rng(5).integers(0, 256, len(data) - 200, np.uint8).tobytes()
    (d / "junk.avi").write_bytes(bytes(junk))
    (d / "empty.avi").write_bytes(b"")
    zero = cv2.VideoWriter(
        str(d / "zero.avi"), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (160, 96)
    )
    zero.release()
    (d / "text.mp4").write_text("not a video at all\n")
    return {
        "truncated": (d / "cut.avi", "cut.avi"),
        "corrupt": (d / "junk.avi", "junk.avi"),
        "empty": (d / "empty.avi", "empty.avi"),
        "zero frames": (d / "zero.avi", "zero.avi"),
        "not a video": (d / "text.mp4", "text.mp4"),
        "missing": (d / "nope.avi", "nope.avi"),
    }


@pytest.mark.parametrize(
    "case", ["truncated", "corrupt", "empty", "zero frames", "not a video", "missing"]
)
def test_a_bad_clip_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    clip, name = _bad_clips(tmp_path)[case]
    rc = main(["video", str(clip), "--surface", "sphere-concave", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and err.startswith("adaproj video: error:"), err
    assert name in err
    assert not (tmp_path / "o" / "frames.json").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--frames", "0"], "--frames"),
        (["--surface", "nope.npz"], "nope.npz"),
        (["--mask", "{d}/tall.png"], "aspect"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    clip = write_clip(tmp_path / "c.avi", "MJPG", n=4)
    cv2.imwrite(str(tmp_path / "tall.png"), np.zeros((300, 20), np.uint8))
    base = {"--surface": "sphere-concave", "--out": str(tmp_path / "o")}
    for k, v in zip(args[::2], args[1::2], strict=True):
        base[k] = v.format(d=tmp_path)
    argv = ["video", str(clip)] + [x for kv in base.items() for x in kv]
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and message in err, err
