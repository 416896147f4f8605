"""The content store: names, quota, image and clip checks, offsets, atomic commit."""

from __future__ import annotations

from pathlib import Path

import pytest

from adaproj_edge.content.video import VideoLimits
from adaproj_edge.errors import (
    ContentError,
    ContentNotFoundError,
    ImageError,
    QuotaError,
    UploadOffsetError,
    VideoError,
)
from adaproj_edge.link.store import ActiveRecord, ContentStore, Limits, check_name
from tests.content.clips import H264, write_clip
from tests.link.media import jpeg_bytes, png_bomb, png_bytes


def files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


@pytest.mark.parametrize(
    "raw",
    [
        "../x.png",
        "/../x.png",
        "a/b.png",
        "..png",
        ".hidden.png",
        "x.png/",
        "//x.png",
        "",
        "x.exe",
        "x.png\x00.txt",
        "ä.png",
        "x" * 70 + ".png",
        "C:\\x.png",
    ],
)
def test_bad_names_refused(raw: str) -> None:
    with pytest.raises(ContentError, match="not allowed"):
        check_name(raw)


def test_good_names() -> None:
    assert check_name("/Poster_1.final.PNG") == "Poster_1.final.PNG"
    assert check_name("a.jpeg") == "a.jpeg"


def test_upload_in_chunks_commits_at_the_end(store: ContentStore) -> None:
    data = png_bytes(64, 48)
    assert store.begin("/p.png", len(data), data[:100]) == 100
    assert not (store.root / "p.png").exists()
    assert store.pending_for("p.png") is not None
    assert store.append("p.png", 100, data[100:]) == len(data)
    assert (store.root / "p.png").read_bytes() == data
    assert store.pending() == []
    assert [i.name for i in store.items()] == ["p.png"]
    assert store.items()[0].width == 64


def test_jpeg_accepted(store: ContentStore) -> None:
    data = jpeg_bytes(40, 30)
    store.begin("j.jpg", len(data), data)
    assert store.items()[0].height == 30


def test_offset_mismatch_says_where_to_resume(store: ContentStore) -> None:
    data = png_bytes(64, 48)
    store.begin("p.png", len(data), data[:50])
    with pytest.raises(UploadOffsetError) as e:
        store.append("p.png", 80, data[80:90])
    assert e.value.expected == 50
    with pytest.raises(UploadOffsetError) as e:
        store.append("q.png", 10, b"x")
    assert e.value.expected == 0


def test_restart_at_zero_discards_the_partial(store: ContentStore) -> None:
    data = png_bytes(64, 48)
    store.begin("p.png", len(data), data[:50])
    store.begin("p.png", len(data), data[:20])
    assert store.pending_for("p.png") is not None
    assert store.pending_for("p.png").received == 20  # type: ignore[union-attr]


def test_more_than_declared_refused(store: ContentStore) -> None:
    data = png_bytes(64, 48)
    with pytest.raises(ContentError, match="declared"):
        store.begin("p.png", 10, data[:11])


def test_over_quota_refused_before_writing(tmp_path: Path) -> None:
    s = ContentStore(tmp_path / "s", Limits(quota=10_000))
    data = png_bytes(100, 100)
    before = files(s.root)
    with pytest.raises(QuotaError, match="does not fit"):
        s.begin("big.png", len(data), data[:1000])
    assert files(s.root) == before


def test_item_limit(tmp_path: Path) -> None:
    s = ContentStore(tmp_path / "s", Limits(max_items=1))
    data = png_bytes(8, 8)
    s.begin("a.png", len(data), data)
    s.begin("a.png", len(data), data)  # replacing is fine
    with pytest.raises(QuotaError, match="most"):
        s.begin("b.png", len(data), data)


@pytest.mark.parametrize(
    "data",
    [
        b"hello, not an image at all, really",
        b"GIF89a" + b"\x00" * 40,
        b"\x89PNG\r\n\x1a\n" + b"\x00" * 5,
    ],
)
def test_non_images_refused_and_nothing_left(store: ContentStore, data: bytes) -> None:
    before = files(store.root)
    with pytest.raises(ImageError):
        store.begin("x.png", len(data), data)
    assert files(store.root) == before


def test_truncated_png_refused_at_commit(store: ContentStore) -> None:
    data = png_bytes(64, 48)
    cut = data[:-40] + b"\x00" * 40
    store.begin("x.png", len(cut), cut[:64])
    with pytest.raises(ImageError):
        store.append("x.png", 64, cut[64:])
    assert files(store.root) == []


def test_decompression_bomb_refused_from_its_header(store: ContentStore) -> None:
    bomb = png_bomb()
    before = files(store.root)
    with pytest.raises(ImageError, match="refused before decoding"):
        store.begin("bomb.png", len(bomb), bomb[:4096])
    assert files(store.root) == before


def test_failed_upload_leaves_committed_and_active_alone(store: ContentStore) -> None:
    good = png_bytes(32, 32, seed=1)
    store.begin("show.png", len(good), good)
    store.set_active(ActiveRecord("show.png", None, {"mode": "conformal"}))
    other = png_bytes(32, 32, seed=2)
    store.begin("show.png", len(other), other[:100])  # replacement started, never finished
    assert (store.root / "show.png").read_bytes() == good
    assert store.active() == ActiveRecord("show.png", None, {"mode": "conformal"})
    broken = other[:-10] + b"\x00" * 10
    store.begin("show.png", len(broken), broken[:100])
    with pytest.raises(ImageError):
        store.append("show.png", 100, broken[100:])
    assert (store.root / "show.png").read_bytes() == good


def test_pending_survives_reopen(store: ContentStore) -> None:
    data = png_bytes(64, 48)
    store.begin("p.png", len(data), data[:77])
    again = ContentStore(store.root)
    p = again.pending_for("p.png")
    assert p is not None and (p.received, p.total) == (77, len(data))
    assert again.append("p.png", 77, data[77:]) == len(data)


def test_oldest_pending_dropped_beyond_the_limit(store: ContentStore) -> None:
    data = png_bytes(16, 16)
    for i in range(6):
        store.begin(f"p{i}.png", len(data), data[:40])
    names = [p.name for p in store.pending()]
    assert len(names) == 4 and "p5.png" in names


def test_delete_and_active_guard(store: ContentStore) -> None:
    data = png_bytes(16, 16)
    store.begin("a.png", len(data), data)
    store.set_active(ActiveRecord("a.png"))
    with pytest.raises(ContentError, match="being shown"):
        store.delete("a.png")
    store.begin("b.png", len(data), data)
    store.set_active(ActiveRecord("b.png"))
    store.delete("a.png")
    with pytest.raises(ContentNotFoundError):
        store.delete("a.png")


def test_read_and_digest(store: ContentStore) -> None:
    import hashlib
    import zlib

    data = png_bytes(16, 16)
    store.begin("a.png", len(data), data)
    assert store.read("a.png", 10, 5) == (data[10:15], len(data))
    assert store.digest("a.png", "sha256")[0] == hashlib.sha256(data).digest()
    assert store.digest("a.png", "crc32", 3, 20) == (zlib.crc32(data[3:23]), 20)
    with pytest.raises(UploadOffsetError):
        store.read("a.png", len(data) + 1, 5)


def test_whole_but_uncommitted_upload_is_committed_on_open(store: ContentStore) -> None:
    data = png_bytes(32, 32)
    store.begin("p.png", len(data), data[:50])
    part = store.incoming / f"{len(data)}.p.png"
    with part.open("ab") as f:  # the last chunk landed, then the server died before the rename
        f.write(data[50:])
    again = ContentStore(store.root)
    assert (again.root / "p.png").read_bytes() == data and again.pending() == []


def test_append_at_the_end_commits(store: ContentStore) -> None:
    data = png_bytes(32, 32)
    store.begin("p.png", len(data), data[:50])
    with (store.incoming / f"{len(data)}.p.png").open("ab") as f:
        f.write(data[50:])
    assert store.append("p.png", len(data), b"") == len(data)
    assert (store.root / "p.png").read_bytes() == data


# ---- video clips -------------------------------------------------------------------


def clip_bytes(
    tmp_path: Path, name: str, fourcc: str, n: int = 20, size: tuple[int, int] = (160, 96)
) -> bytes:
    return write_clip(tmp_path / name, fourcc, n=n, size=size, fps=20).read_bytes()


def upload(store: ContentStore, name: str, data: bytes, chunk: int = 4000) -> None:
    store.begin(name, len(data), data[:chunk])
    for off in range(chunk, len(data), chunk):
        store.append(name, off, data[off : off + chunk])


@pytest.mark.parametrize(
    ("name", "fourcc"), [("c.avi", "MJPG"), ("c.mp4", "mp4v"), ("c.mkv", "MJPG")]
)
def test_clips_accepted_and_listed_with_duration(
    store: ContentStore, tmp_path: Path, name: str, fourcc: str
) -> None:
    data = clip_bytes(tmp_path, name, fourcc)
    upload(store, name, data)
    assert (store.root / name).read_bytes() == data
    [item] = store.items()
    assert (item.kind, item.width, item.height, item.duration) == ("video", 160, 96, 1.0)


def test_h264_clip_accepted(store: ContentStore) -> None:
    upload(store, "h.mp4", H264.read_bytes())
    assert store.items()[0].duration == 1.0 and store.items()[0].kind == "video"
    assert store.items()[0].width == 320


def test_image_items_have_no_duration(store: ContentStore) -> None:
    data = png_bytes(40, 30)
    upload(store, "p.png", data)
    assert store.items()[0].duration is None and store.items()[0].kind == "image"


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("truncated", "truncated or corrupt"),
        ("codec", "ffv1 codec"),
        ("long", "longer than the 0.5 s"),
        ("large", "a clip may be at most 100 px"),
        ("empty", "no frames|cannot be opened"),
    ],
)
def test_bad_clips_refused_at_commit_and_nothing_left(
    tmp_path: Path, case: str, message: str
) -> None:
    video = VideoLimits(max_duration=0.5) if case == "long" else VideoLimits()
    if case == "large":
        video = VideoLimits(max_side=100)
    store = ContentStore(tmp_path / "s", Limits(video=video))
    good = clip_bytes(tmp_path, "good.avi", "MJPG", n=8, size=(64, 48))
    upload(store, "show.avi", good)
    store.set_active(ActiveRecord("show.avi"))
    data = {
        "truncated": clip_bytes(tmp_path, "c.avi", "MJPG")[:-3000],
        "codec": clip_bytes(tmp_path, "f.mkv", "FFV1"),
        "long": clip_bytes(tmp_path, "l.avi", "MJPG"),
        "large": clip_bytes(tmp_path, "b.avi", "MJPG"),
        "empty": clip_bytes(tmp_path, "e.avi", "MJPG", n=0),
    }[case]
    name = "f.mkv" if case == "codec" else "show.avi"
    with pytest.raises(VideoError, match=message):
        upload(store, name, data)
    assert files(store.root) == [".active.json", "show.avi"]
    assert (store.root / "show.avi").read_bytes() == good
    assert store.active() == ActiveRecord("show.avi")


@pytest.mark.parametrize(
    ("name", "head", "message"),
    [
        ("x.mp4", b"RIFF\x00\x00\x00\x00AVI LIST" + b"\x00" * 20, r"named \.mp4 but holds an AVI"),
        ("x.mkv", b"#EXTM3U\nhttp://example.invalid/a.ts\n" + b"\x00" * 8, "not an MP4"),
        ("x.avi", b"\x89PNG\r\n\x1a\n" + b"\x00" * 30, "not an MP4"),
    ],
)
def test_clip_heads_refused_before_writing(
    store: ContentStore, name: str, head: bytes, message: str
) -> None:
    before = files(store.root)
    with pytest.raises(VideoError, match=message):
        store.begin(name, 100_000, head)
    assert files(store.root) == before


def test_clip_names(store: ContentStore) -> None:
    assert check_name("/Film_1.MP4") == "Film_1.MP4"
    assert check_name("a.mkv") == "a.mkv" and check_name("a.avi") == "a.avi"
    for bad in ("a.mov", "a.webm", "a.m3u8"):
        with pytest.raises(ContentError, match="not allowed"):
            check_name(bad)
