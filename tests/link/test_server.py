"""The dispatcher, message by message: replies, SMP errors, and what is ignored."""

from __future__ import annotations

import logging
import struct
from typing import Any

import cbor2
import pytest
from smp import file_management as smpfs
from smp import os_management as smpos
from smp.error import MGMT_ERR
from smp.file_management import FS_MGMT_ERR

from adaproj_edge.link.framing import START
from adaproj_edge.link.host_requests import (
    ActivateWrite,
    DeleteWrite,
    ListRead,
    ScreenshotRead,
    StatusRead,
)
from adaproj_edge.link.ids import ADAPROJ_GROUP
from adaproj_edge.link.message import HEADER
from adaproj_edge.link.server import Server
from tests.link.media import png_bomb, png_bytes


def raw(op: int, group: int, cmd: int, body: bytes, *, version: int = 1, seq: int = 7) -> bytes:
    return HEADER.pack(version << 3 | op, 0, len(body), group, seq, cmd) + body


def answer(server: Server, message: bytes) -> dict[str, Any]:
    reply = server.handle(message)
    assert reply is not None
    op, _flags, length, _group, seq, _cmd = struct.unpack_from("!BBHHBB", reply)
    assert seq == message[6] and length == len(reply) - 8
    assert op & 0b111 in (1, 3)
    body = cbor2.loads(reply[8:])
    assert isinstance(body, dict)
    return body


def ask(server: Server, request: Any) -> dict[str, Any]:
    return answer(server, bytes(request.BYTES))


def upload(server: Server, name: str, data: bytes, chunk: int = 1000) -> dict[str, Any]:
    r = ask(server, smpfs.FileUploadRequest(name=name, off=0, data=data[:chunk], len=len(data)))
    while "off" in r and r["off"] < len(data):
        off = r["off"]
        r = ask(server, smpfs.FileUploadRequest(name=name, off=off, data=data[off : off + chunk]))
    return r


def test_echo_and_params(server: Server) -> None:
    assert ask(server, smpos.EchoWriteRequest(d="hello")) == {"r": "hello"}
    assert ask(server, smpos.MCUMgrParametersReadRequest()) == {"buf_size": 4096, "buf_count": 1}


def test_reset_runs_the_hook_after_the_reply(server: Server) -> None:
    calls: list[int] = []
    server.on_reset = lambda: calls.append(1)
    assert ask(server, smpos.ResetWriteRequest()) == {}
    assert server.after_reply is not None and calls == []


def test_file_upload_status_hash_download(server: Server) -> None:
    data = png_bytes(50, 40)
    assert upload(server, "/a.png", data) == {"off": len(data)}
    assert ask(server, smpfs.FileStatusRequest(name="/a.png")) == {"len": len(data)}
    h = ask(server, smpfs.FileHashChecksumRequest(name="/a.png", type="sha256"))
    import hashlib

    assert h["output"] == hashlib.sha256(data).digest() and h["len"] == len(data)
    d = ask(server, smpfs.FileDownloadRequest(name="/a.png", off=0))
    assert d["len"] == len(data) and data.startswith(d["data"])
    tail = ask(server, smpfs.FileDownloadRequest(name="/a.png", off=len(data)))
    assert tail["data"] == b""


def test_file_errors_are_group_errors(server: Server) -> None:
    missing = ask(server, smpfs.FileStatusRequest(name="/nope.png"))
    assert missing == {"err": {"group": 8, "rc": FS_MGMT_ERR.FILE_NOT_FOUND}}
    data = png_bytes(50, 40)
    ask(server, smpfs.FileUploadRequest(name="b.png", off=0, data=data[:100], len=len(data)))
    bad = ask(server, smpfs.FileUploadRequest(name="b.png", off=300, data=data[300:400]))
    assert bad == {"err": {"group": 8, "rc": FS_MGMT_ERR.FILE_OFFSET_NOT_VALID}, "len": 100}
    h = answer(server, raw(0, 8, 2, cbor2.dumps({"name": "b.png", "type": "md5"})))
    assert h["err"]["rc"] == FS_MGMT_ERR.CHECKSUM_HASH_NOT_FOUND


def test_version_1_requests_get_rc_and_reason(server: Server) -> None:
    r = answer(server, raw(0, 8, 1, cbor2.dumps({"name": "nope.png"}), version=0))
    assert r["rc"] == MGMT_ERR.ENOENT and "no item" in r["rsn"]


def test_refusals_are_clear_and_write_nothing(server: Server) -> None:
    root = server.store.root
    before = sorted(p.name for p in root.rglob("*"))
    cases = {
        "../../etc/passwd.png": b"\x89PNG\r\n\x1a\n" + b"\x00" * 40,
        "x.png": b"MZ this is an exe, not an image........",
        "bomb.png": png_bomb()[:2000],
    }
    for name, data in cases.items():
        r = ask(server, smpfs.FileUploadRequest(name=name, off=0, data=data, len=10**5))
        assert r["rc"] == MGMT_ERR.EINVAL and r["rsn"], r
    big = ask(server, smpfs.FileUploadRequest(name="big.png", off=0, data=b"", len=5 * 2**20))
    assert big["rc"] == MGMT_ERR.ENOMEM and "fit" in big["rsn"]
    assert sorted(p.name for p in root.rglob("*")) == before


def test_adaproj_group_commands(server: Server) -> None:
    data = png_bytes(60, 40, seed=3)
    mask = png_bytes(60, 40, seed=4)
    upload(server, "img.png", data)
    upload(server, "mask.png", mask)
    listed = ask(server, ListRead())
    assert [i["name"] for i in listed["items"]] == ["img.png", "mask.png"]
    assert listed["active"] is None and listed["quota"] == 4 * 2**20
    settings = {"mode": "conformal", "threshold": 0.25}
    act = ask(server, ActivateWrite(image="img.png", mask="mask.png", settings=settings))
    assert act["active"] == {"image": "img.png", "mask": "mask.png", "settings": settings}
    bad = ask(server, ActivateWrite(image="img.png", settings={"mode": "fisheye"}))
    assert bad["rc"] == MGMT_ERR.EINVAL and "mode" in bad["rsn"]
    gone = ask(server, ActivateWrite(image="nothing.png"))
    assert gone["rc"] == MGMT_ERR.ENOENT
    shot = ask(server, ScreenshotRead(off=0))
    assert shot["data"].startswith(b"\x89PNG") and shot["len"] >= len(shot["data"])
    assert ask(server, DeleteWrite(name="img.png"))["rc"] == MGMT_ERR.EINVAL  # shown
    ask(server, ActivateWrite(image="mask.png"))
    assert ask(server, DeleteWrite(name="img.png")) == {}


def test_malformed_requests_get_errors(server: Server) -> None:
    cases = [
        (raw(2, 0, 0, b"\xff\xff"), MGMT_ERR.EINVAL),  # not CBOR
        (raw(2, 0, 0, cbor2.dumps([1, 2])), MGMT_ERR.EINVAL),  # not a map
        (raw(2, 0, 0, cbor2.dumps({"d": 5})), MGMT_ERR.EINVAL),  # wrong type
        (raw(2, 0, 0, cbor2.dumps({1: "x"})), MGMT_ERR.EINVAL),  # int key
        (raw(2, 0, 0, bytes.fromhex("a16164c1")), MGMT_ERR.EINVAL),  # a tagged value
        (raw(2, 0, 0, bytes.fromhex("a161648181818181818101")), MGMT_ERR.EINVAL),  # deep
        (raw(2, 0, 0, cbor2.dumps({"d": "x"}))[:-1], MGMT_ERR.EINVAL),  # length mismatch
        (raw(2, 0, 0, cbor2.dumps({"d": "x"}), version=3), MGMT_ERR.UNSUPPORTED_TOO_NEW),
        (raw(0, 0, 0, b""), MGMT_ERR.ENOTSUP),  # echo is write-only
        (raw(0, 99, 0, b""), MGMT_ERR.ENOTSUP),
        (raw(0, ADAPROJ_GROUP, 200, b""), MGMT_ERR.ENOTSUP),
        (raw(2, 8, 0, cbor2.dumps({"name": "a.png", "off": -1, "data": b""})), MGMT_ERR.EINVAL),
        (raw(2, 8, 0, cbor2.dumps({"name": "a.png", "off": 0, "data": b""})), MGMT_ERR.EINVAL),
        (raw(2, 8, 0, cbor2.dumps({"name": "a.png", "off": True, "data": b""})), MGMT_ERR.EINVAL),
    ]
    for message, rc in cases:
        r = answer(server, message)
        assert r.get("rc") == rc, (message.hex(), r)
        assert isinstance(r.get("rsn"), str)


def test_responses_and_short_messages_are_ignored(server: Server) -> None:
    assert server.handle(b"\x01\x02") is None
    assert server.handle(raw(1, 0, 0, b"")) is None
    assert server.handle(raw(3, 0, 0, b"")) is None
    assert server.counters["ignored"] == 3


def test_new_version_of_the_shown_image_is_shown(server: Server) -> None:
    upload(server, "a.png", png_bytes(60, 40, seed=1))
    ask(server, ActivateWrite(image="a.png"))
    before = ask(server, ScreenshotRead(off=0))["data"]
    upload(server, "a.png", png_bytes(60, 40, seed=2))
    assert ask(server, ScreenshotRead(off=0))["data"] != before


def test_a_reply_too_big_for_a_frame_is_an_error(server: Server) -> None:
    class Chatty:
        def status(self) -> dict[str, Any]:
            return {"log": "x" * 70_000}

    server.device = Chatty()  # type: ignore[assignment]
    assert ask(server, StatusRead())["rc"] == MGMT_ERR.EMSGSIZE


def test_resume_probes_are_neither_errors_nor_warnings(
    server: Server, caplog: pytest.LogCaptureFixture
) -> None:
    data = png_bytes(50, 40)
    with caplog.at_level(logging.DEBUG, logger="adaproj_edge.link"):
        ask(server, smpfs.FileStatusRequest(name="/p.png"))  # not there yet
        ask(server, smpfs.FileHashChecksumRequest(name="/p.png", type="sha256"))
        ask(server, smpfs.FileUploadRequest(name="p.png", off=0, data=data[:100], len=len(data)))
        moved = ask(server, smpfs.FileUploadRequest(name="p.png", off=300, data=data[300:]))
        assert moved["len"] == 100  # where to go on
    assert server.counters["probes"] == 3 and server.counters["errors"] == 0
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]

    caplog.clear()
    assert ask(server, ActivateWrite(image="nothing.png"))["rc"] == MGMT_ERR.ENOENT
    assert server.counters["errors"] == 1
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warned) == 1 and "nothing.png" in warned[0]


def test_a_flood_of_refusals_is_summarised(
    server: Server, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING, logger="adaproj_edge.link"):
        for i in range(40):
            answer(server, raw(2, 0, 0, cbor2.dumps({"d": i})))  # echo of a number: refused
        assert ask(server, smpos.EchoWriteRequest(d="ok")) == {"r": "ok"}
    warned = [r.getMessage() for r in caplog.records]
    assert len(warned) == 4  # the first three, then one summary at the next success
    assert warned[-1].startswith("40 requests refused before this good one")
    assert server.counters["errors"] == 40


def test_status_counts_the_frames_dropped(server: Server) -> None:
    assert list(server.decoder.feed(START + b"AAAAB\n")) == []
    link = ask(server, StatusRead())["link"]
    assert link["frames_dropped"] == {"bad base64": 1}
    assert set(link) == {"requests", "errors", "ignored", "probes", "frames_dropped"}
