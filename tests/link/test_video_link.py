"""Video clips over the real link: ``adaproj push``/``device list`` and ``smpclient``
against the server on a pty pair; bad clips refused at upload with the reason."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from adaproj_edge import cli
from adaproj_edge.errors import LinkError
from adaproj_edge.link import client
from tests.content.clips import H264, write_clip
from tests.link.conftest import Running


def test_push_a_clip_resumes_shows_progress_and_lists_duration(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = write_clip(tmp_path / "walk.avi", "MJPG", n=30, fps=20)
    data = src.read_bytes()
    running.store.begin("walk.avi", len(data), data[:6000])  # a transfer cut short
    assert cli.main(["push", str(src), "--activate", "--port", running.pty.path]) == 0
    captured = capsys.readouterr()
    assert "resumed at byte 6000" in captured.out and "showing walk.avi" in captured.out
    assert "100.0%" in captured.err and "walk.avi [" in captured.err  # the progress bar
    assert (running.store.root / "walk.avi").read_bytes() == data
    assert cli.main(["push", str(H264), "--port", running.pty.path]) == 0
    capsys.readouterr()
    assert cli.main(["device", "list", "--port", running.pty.path]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if "walk.avi" in x)
    assert line.startswith("*") and "160x96" in line and "1.5 s" in line
    line = next(x for x in out.splitlines() if "h264.mp4" in x)
    assert "320x180" in line and "1.0 s" in line
    shot = tmp_path / "shot.png"
    assert cli.main(["device", "screenshot", str(shot), "--port", running.pty.path]) == 0
    assert shot.read_bytes().startswith(b"\x89PNG")


def test_smpclient_upload_of_a_truncated_clip_is_refused_with_the_reason(
    running: Running, tmp_path: Path
) -> None:
    data = write_clip(tmp_path / "c.mkv", "MJPG", n=30).read_bytes()
    cut = data[: len(data) * 2 // 3]

    async def go() -> None:
        async with client.connect(running.pty.path) as c:
            with pytest.raises(LinkError, match="truncated or corrupt"):
                await client.upload(c, cut, "cut.mkv")
            listed = await client.call(c, client.ListRead())
            assert listed.items == [] and listed.pending == []

    asyncio.run(go())
    assert sorted(p.name for p in running.store.root.iterdir()) == [".incoming"]
    assert list(running.store.incoming.iterdir()) == []


@pytest.mark.parametrize(
    ("fourcc", "name", "keep", "message"),
    [
        ("MJPG", "cut.avi", 0.5, "truncated or corrupt"),
        ("FFV1", "lossless.mkv", 1.0, "codec; only H.264"),
        ("MJPG", "empty.avi", 1.0, "no frames|cannot be opened"),
    ],
)
def test_push_refuses_bad_clips_before_connecting(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    fourcc: str,
    name: str,
    keep: float,
    message: str,
) -> None:
    n = 0 if name.startswith("empty") else 20
    data = write_clip(tmp_path / name, fourcc, n=n).read_bytes()
    src = tmp_path / f"local-{name}"
    src.write_bytes(data[: int(len(data) * keep)])
    assert cli.main(["push", str(src), "--port", "/dev/null-nothing"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert any(m in err for m in message.split("|"))
