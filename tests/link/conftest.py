"""Fixtures for the link tests: images, a store, a server on a pty pair."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.server import Server, serve
from adaproj_edge.link.store import ContentStore, Limits
from tests.link.media import png_bytes


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
