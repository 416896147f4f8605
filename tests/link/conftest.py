"""Fixtures for the link tests: images, a store, a server on a pty pair (clean or noisy)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.message import parse_header
from adaproj_edge.link.server import Server, serve
from adaproj_edge.link.store import ContentStore, Limits
from tests.link.media import png_bytes
from tests.link.noise import NoisyPort

UPLOAD = (8, 0, 2)
"""(group, command, op) of an upload request: file group, upload, write."""


@pytest.fixture
def store(tmp_path: Path) -> ContentStore:
    return ContentStore(tmp_path / "store", Limits(quota=4 * 2**20))


@pytest.fixture
def server(store: ContentStore) -> Server:
    return Server(store, StandaloneDevice(160, 100), buf_size=4096)


@dataclass
class Running:
    pty: PtyPair
    server: Server
    store: ContentStore


@pytest.fixture
def running(server: Server) -> Iterator[Running]:
    """The server answering on a pty pair, in a thread; clients open ``pty.path``."""
    pty = PtyPair.open()
    stop = threading.Event()
    t = threading.Thread(target=serve, args=(pty.port(), server, stop), daemon=True)
    t.start()
    try:
        yield Running(pty, server, server.store)
    finally:
        stop.set()
        t.join(5)
        pty.close()


@pytest.fixture
def png() -> bytes:
    return png_bytes(120, 80, seed=1)


@dataclass
class NoisyLine:
    """The fixture's server answering on a pty through a :class:`NoisyPort`."""

    pty: PtyPair
    server: Server
    port: NoisyPort
    uploads: list[int]  # message size of every upload request handled

    def requests(self) -> int:
        return self.server.counters["requests"]


@pytest.fixture
def line(server: Server) -> Iterator[NoisyLine]:
    pty = PtyPair.open()
    port = NoisyPort(pty.port())
    uploads: list[int] = []
    handle = server.handle

    def counting(message: bytes) -> bytes | None:
        op, _v, _f, _n, group, _seq, cmd = parse_header(message)
        if (group, cmd, op) == UPLOAD:
            uploads.append(len(message))
        return handle(message)

    server.handle = counting  # type: ignore[method-assign]
    stop = threading.Event()
    t = threading.Thread(target=serve, args=(port, server, stop), daemon=True)
    t.start()
    try:
        yield NoisyLine(pty, server, port, uploads)
    finally:
        stop.set()
        t.join(5)
        pty.close()
