"""Video clips: probe, checks with reasons, the looping reader, corrupted bytes."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adaproj_edge.content.video import (
    VideoLimits,
    VideoReader,
    check_video,
    check_video_head,
    container_of,
    probe,
)
from adaproj_edge.errors import VideoError
from tests.content.clips import H264, frame, write_clip


@pytest.mark.parametrize(
    ("fourcc", "ext", "codec"),
    [("MJPG", ".avi", "MJPEG"), ("mp4v", ".mp4", "MPEG-4"), ("MJPG", ".mkv", "MJPEG")],
)
def test_clips_written_by_opencv_pass(tmp_path: Path, fourcc: str, ext: str, codec: str) -> None:
    path = write_clip(tmp_path / f"c{ext}", fourcc, n=12, fps=24)
    info = check_video(path)
    assert (info.width, info.height, info.frame_count, info.fps) == (160, 96, 12, 24.0)
    assert info.codec_name == codec and info.duration == pytest.approx(0.5)


def test_h264_decodes() -> None:
    info = check_video(H264)
    assert info.codec_name == "H.264" and (info.width, info.height) == (320, 180)
    assert info.frame_count == 30 and info.fps == 30.0
    with VideoReader(H264, info) as reader:
        frames = [reader.next() for _ in range(30)]
    assert all(f.ok and f.image is not None for f in frames)
    first, last = frames[0].image, frames[-1].image
    assert first is not None and last is not None

    # the disc (orange: B low, R high) moves right by 8 px a frame
    def disc_x(img: np.ndarray) -> float:
        orange = (img[:, :, 2] > 200) & (img[:, :, 0] < 80) & (img[:, :, 1] > 120)
        return float(np.nonzero(orange)[1].mean())

    assert disc_x(last) - disc_x(first) == pytest.approx(8 * 29, abs=4)


def test_unsupported_codec_refused(tmp_path: Path) -> None:
    path = write_clip(tmp_path / "c.mkv", "FFV1", n=5)
    with pytest.raises(VideoError, match=r"codec; only H\.264, MPEG-4 and MJPEG"):
        check_video(path)


@pytest.mark.parametrize(("ext", "fourcc"), [(".avi", "MJPG"), (".mkv", "MJPG"), (".mp4", "mp4v")])
@pytest.mark.parametrize("keep", [0.9, 0.5, 0.1])
def test_truncated_clips_refused(tmp_path: Path, ext: str, fourcc: str, keep: float) -> None:
    data = write_clip(tmp_path / f"c{ext}", fourcc, n=20).read_bytes()
    cut = tmp_path / f"cut{ext}"
    cut.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(VideoError, match="truncated or corrupt"):
        check_video(cut)


def test_a_single_frame_clip_passes(tmp_path: Path) -> None:
    info = check_video(write_clip(tmp_path / "one.avi", "MJPG", n=1))
    assert info.frame_count == 1


def test_zero_frames_refused(tmp_path: Path) -> None:
    path = write_clip(tmp_path / "c.avi", "MJPG", n=0)
    with pytest.raises(VideoError, match=r"no frames|cannot be opened"):
        check_video(path)


@pytest.mark.parametrize(
    ("limits", "message"),
    [
        (VideoLimits(max_frames=10), "20 frames, more than 10"),
        (VideoLimits(max_duration=0.5), "lasts 1.0 s, longer than the 0.5 s"),
        (VideoLimits(max_side=100), "160x96; a clip may be at most 100 px"),
        (VideoLimits(max_pixels=160 * 95), "160x96"),
        (VideoLimits(max_fps=15), "runs at 20 fps"),
    ],
)
def test_limits_refused_with_the_reason(tmp_path: Path, limits: VideoLimits, message: str) -> None:
    path = write_clip(tmp_path / "c.avi", n=20, fps=20)
    with pytest.raises(VideoError, match=message):
        check_video(path, limits=limits)


def test_containers_told_by_their_first_bytes(tmp_path: Path) -> None:
    avi = write_clip(tmp_path / "c.avi").read_bytes()[:16]
    assert container_of(avi) == "avi" and container_of(H264.read_bytes()[:16]) == "mp4"
    check_video_head(avi, "x.avi")
    with pytest.raises(VideoError, match=r"named \.mp4 but holds an AVI"):
        check_video_head(avi, "x.mp4")
    with pytest.raises(VideoError, match="not an MP4, AVI or Matroska"):
        check_video_head(b"#EXTM3U\n#EXT-X-VERSION:3\n", "x.mp4")
    playlist = tmp_path / "list.mp4"
    playlist.write_bytes(b"#EXTM3U\nfile:///etc/passwd\n")
    with pytest.raises(VideoError, match="not an MP4"):
        probe(playlist)


def test_reader_loops_at_the_clip_rate(tmp_path: Path) -> None:
    path = write_clip(tmp_path / "c.avi", n=10, fps=20)
    with VideoReader(path) as reader:
        frames = [reader.next() for _ in range(25)]
        assert [f.index for f in frames] == [*range(10), *range(10), *range(5)]
        assert [f.loop for f in frames[9:11]] == [0, 1]
        assert [f.t for f in frames[:3]] == pytest.approx([0.0, 0.05, 0.1])
        assert frames[12].t == pytest.approx(0.6)
        assert all(f.ok for f in frames)
        assert np.array_equal(frames[3].image, frames[13].image)


def test_reader_at_skips_repeats_and_goes_back(tmp_path: Path) -> None:
    path = write_clip(tmp_path / "c.avi", n=10, fps=20)
    with VideoReader(path) as reader:
        direct = [reader.next().image for _ in range(10)]
        a = reader.at(0.26)  # frame 5 of the first loop: the reader goes back
        assert (a.loop, a.index) == (0, 5) and np.array_equal(a.image, direct[5])
        assert reader.at(0.27) is a  # same frame: no decode
        b = reader.at(0.41)
        assert (b.loop, b.index) == (0, 8) and np.array_equal(b.image, direct[8])
        c = reader.at(0.61)  # next loop, frame 2
        assert (c.loop, c.index, c.t) == (1, 2, pytest.approx(0.6))
        assert np.array_equal(c.image, direct[2])
        assert reader.at(-1.0).index == 0


def test_mid_play_failure_keeps_the_last_good_frame(tmp_path: Path) -> None:
    src = write_clip(tmp_path / "c.avi", n=20)
    path = tmp_path / "play.avi"
    shutil.copy(src, path)
    with VideoReader(path, check_video(path)) as reader:
        good = [reader.next() for _ in range(3)]
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 3])  # the file is cut while it plays
        later = [reader.next() for _ in range(20)]
    assert all(f.ok for f in good)
    bad = [f for f in later if not f.ok]
    assert bad, "the cut file should fail before its end"
    assert "does not decode" in (bad[0].error or "")
    ok_before = later[: later.index(bad[0])]
    last_good = (ok_before[-1] if ok_before else good[-1]).image
    assert all(np.array_equal(f.image, last_good) for f in bad[:3])


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    d = tmp_path_factory.mktemp("seeds")
    return {
        ".avi": write_clip(d / "s.avi", "MJPG", n=6, size=(64, 48)).read_bytes(),
        ".mp4": write_clip(d / "s.mp4", "mp4v", n=6, size=(64, 48)).read_bytes(),
        ".mkv": write_clip(d / "s.mkv", "MJPG", n=6, size=(64, 48)).read_bytes(),
        ".h264.mp4": H264.read_bytes(),
    }


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    kind=st.sampled_from([".avi", ".mp4", ".mkv", ".h264.mp4"]),
    cut=st.floats(0.0, 1.0),
    flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(1, 255)), max_size=8),
)
def test_corrupted_bytes_never_crash_or_hang(
    seeds: dict[str, bytes],
    tmp_path_factory: pytest.TempPathFactory,
    kind: str,
    cut: float,
    flips: list[tuple[float, int]],
) -> None:
    data = bytearray(seeds[kind][: max(1, int(len(seeds[kind]) * cut))])
    for where, mask in flips:
        data[min(len(data) - 1, int(where * len(data)))] ^= mask
    path = tmp_path_factory.mktemp("fuzz") / f"f{kind}"
    path.write_bytes(bytes(data))
    limits = VideoLimits(max_frames=50)  # the decode is bounded by frames, not a clock
    try:
        info = check_video(path, limits=limits)
    except VideoError as e:
        assert str(e)
        return
    with VideoReader(path, info) as reader:
        for _ in range(info.frame_count + 2):  # plays (or reports) without raising
            f = reader.next()
            assert f.ok or f.error


def test_frame_helper_moves() -> None:
    assert not np.array_equal(frame(0), frame(5))
