"""Real clients over a real pty pair: the smpmgr CLI, smpclient, and our commands."""

from __future__ import annotations

import asyncio
import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

import cbor2
import pytest
from smp import os_management as smpos
from smpclient.requests.file_management import FileHashChecksum

from adaproj_edge import cli
from adaproj_edge.errors import LinkError
from adaproj_edge.hal.serial import FdPort, PtyPair
from adaproj_edge.link import client
from adaproj_edge.link.framing import FrameDecoder, encode_frame
from adaproj_edge.link.host_requests import (
    ActivateWrite,
    DeleteWrite,
    ListRead,
    StatusRead,
    UploadStateRead,
)
from tests.link.conftest import Running
from tests.link.media import png_bytes

ENV = {**os.environ, "COLUMNS": "250", "TERM": "dumb", "NO_COLOR": "1"}


def smpmgr(port: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "smpmgr", "--port", port, "--timeout", "5", *args],
        capture_output=True,
        text=True,
        env=ENV,
        timeout=60,
    )


def test_smpmgr_cli_uploads_downloads_hashes_and_sizes(running: Running, tmp_path: Path) -> None:
    data = png_bytes(40, 30, seed=5)
    src = tmp_path / "src.png"
    src.write_bytes(data)
    up = smpmgr(running.pty.path, "file", "upload", str(src), "/poster.png")
    assert up.returncode == 0, up.stderr + up.stdout
    assert (running.store.root / "poster.png").read_bytes() == data

    size = smpmgr(running.pty.path, "file", "read-size", "/poster.png")
    assert size.returncode == 0 and size.stdout.strip().splitlines()[-1] == str(len(data))

    digest = smpmgr(running.pty.path, "file", "get-hash", "/poster.png")
    assert digest.returncode == 0 and "type='sha256'" in digest.stdout
    assert f"len={len(data)}" in digest.stdout

    out = tmp_path / "back.png"
    down = smpmgr(running.pty.path, "file", "download", "/poster.png", str(out))
    assert down.returncode == 0, down.stderr + down.stdout
    assert out.read_bytes() == data

    bad = smpmgr(running.pty.path, "file", "upload", str(src), "/../../etc/evil.png")
    assert bad.returncode != 0 and "not allowed" in bad.stdout + bad.stderr
    assert sorted(p.name for p in running.store.root.iterdir()) == [".incoming", "poster.png"]


def test_smpclient_drives_every_adaproj_command(running: Running) -> None:
    image = png_bytes(160, 100, seed=6)
    mask = png_bytes(160, 100, seed=7)

    async def go() -> None:
        async with client.connect(running.pty.path) as c:
            seen: list[int] = []
            assert await client.upload(c, image, "wall.png", lambda d, t: seen.append(d)) == 0
            assert seen[-1] == len(image) and len(seen) > 3  # chunks of the 4 KiB buffer
            await client.upload(c, mask, "wall-mask.png")
            listed = await client.call(c, ListRead())
            assert {i["name"] for i in listed.items} == {"wall.png", "wall-mask.png"}
            settings = {"mode": "conformal", "threshold": 0.3}
            act = ActivateWrite(image="wall.png", mask="wall-mask.png", settings=settings)
            assert (await client.call(c, act)).active["settings"] == settings
            status = await client.call(c, StatusRead())
            assert status.device["state"] == "showing" and status.device["image"] == "wall.png"
            assert {"coverage", "warp", "errors"} <= set(status.device)
            assert status.store["items"] == 2 and status.link["requests"] > 0
            png = await client.download_screenshot(c)
            assert png.startswith(b"\x89PNG") and len(png) > 4096  # came in several chunks
            state = await client.call(c, UploadStateRead(name="wall.png"))
            assert (state.off, state.len) == (0, 0)
            with pytest.raises(LinkError, match="being shown"):
                await client.call(c, DeleteWrite(name="wall.png"))
            await client.call(c, ActivateWrite(image="wall-mask.png"))
            await client.call(c, DeleteWrite(name="wall.png"))
            with pytest.raises(LinkError, match="ENOENT"):
                await client.call(c, ActivateWrite(image="wall.png"))

    asyncio.run(go())


def test_push_resumes_and_skips_what_is_there(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = png_bytes(200, 120, seed=8)
    src = tmp_path / "photo.png"
    src.write_bytes(data)
    running.store.begin("photo.png", len(data), data[:5000])  # a transfer cut short
    assert cli.main(["push", str(src), "--activate", "--port", running.pty.path]) == 0
    out = capsys.readouterr().out
    assert "resumed at byte 5000" in out and "showing photo.png" in out
    assert (running.store.root / "photo.png").read_bytes() == data
    assert cli.main(["push", str(src), "--port", running.pty.path]) == 0
    assert "already on the device" in capsys.readouterr().out
    shot = tmp_path / "shot.png"
    assert cli.main(["device", "screenshot", str(shot), "--port", running.pty.path]) == 0
    assert shot.read_bytes().startswith(b"\x89PNG")
    assert cli.main(["device", "delete", "photo.png", "--port", running.pty.path]) == 2
    assert "being shown" in capsys.readouterr().err


def test_push_refuses_bad_local_files_before_connecting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "notes.png"
    bad.write_bytes(b"not an image, just text pretending")
    assert cli.main(["push", str(bad), "--port", "/dev/null-nothing"]) == 2
    assert "not a PNG or JPEG" in capsys.readouterr().err


def test_adaproj_link_serves_a_port_path(tmp_path: Path) -> None:
    """``adaproj link --port`` opens the path with pyserial, as on /dev/ttyGS0."""
    with PtyPair.open() as pty:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "adaproj_edge.cli",
                "link",
                "--port",
                pty.path,
                "--store",
                str(tmp_path / "store"),
            ],
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            host = FdPort(pty.master)
            decoder = FrameDecoder(65536)
            request = smpos.EchoWriteRequest(d="ping", sequence=9)
            replies: list[bytes] = []
            deadline = time.monotonic() + 30
            while not replies and time.monotonic() < deadline:
                host.write(encode_frame(bytes(request.BYTES)))  # until the server is up
                end = time.monotonic() + 1.0
                while not replies and time.monotonic() < end:
                    replies += decoder.feed(host.read(4096, 0.1))
            assert replies, "no reply from adaproj link"
            assert cbor2.loads(replies[0][8:]) == {"r": "ping"} and replies[0][6] == 9
        finally:
            proc.terminate()
            proc.wait(10)
            assert proc.stderr is not None
            proc.stderr.close()


def test_upload_sha_matches(running: Running) -> None:
    data = png_bytes(64, 64, seed=9)

    async def go() -> bytes:
        async with client.connect(running.pty.path) as c:
            await client.upload(c, data, "h.png")
            r = await client.call(c, FileHashChecksum(name="h.png", type="sha256"))
            return bytes(r.output)

    assert asyncio.run(go()) == hashlib.sha256(data).digest()
