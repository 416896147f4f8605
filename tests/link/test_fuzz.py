"""Property-based fuzzing of the decoder and the dispatcher (a few thousand inputs).

The 100,000-input run is ``tools/fuzz_link.py``; this is its CI-sized slice.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from hypothesis import HealthCheck, given, settings

from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.framing import FrameDecoder
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore, Limits
from tests.link.fuzz_cases import (
    dispatch_target,
    messages,
    resync_target,
    resyncs,
    streams,
    wire_target,
)

FUZZ = settings(
    max_examples=1000,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


def make_server(root: Path) -> Server:
    store = ContentStore(root, Limits(quota=2**20, max_file=2**19))
    return Server(store, StandaloneDevice(64, 40), buf_size=2048)


def test_dispatcher_answers_or_ignores_every_message(tmp_path: Path) -> None:
    server = make_server(tmp_path / "store")
    seen: Counter[str] = Counter()

    @FUZZ
    @given(messages())
    def run(message: bytes) -> None:
        dispatch_target(server, message, seen)

    run()
    assert seen["error"] > 0 and seen["ignored"] > 0


def test_wire_stream_never_breaks_the_server(tmp_path: Path) -> None:
    server = make_server(tmp_path / "store")
    decoder = FrameDecoder(server.max_message)
    seen: Counter[str] = Counter()

    @FUZZ
    @given(streams())
    def run(chunks: list[bytes]) -> None:
        wire_target(server, decoder, chunks, seen)

    run()
    assert seen["error"] > 0


def test_after_any_junk_the_next_good_frame_is_answered(tmp_path: Path) -> None:
    server = make_server(tmp_path / "store")
    decoder = FrameDecoder(server.max_message)  # one decoder: each case follows the last
    seen: Counter[str] = Counter()

    @FUZZ
    @given(resyncs())
    def run(case: tuple[list[bytes], bytes]) -> None:
        resync_target(server, decoder, case, seen)

    run()
    assert seen["resynchronised"] >= 1000 and sum(decoder.stats.dropped.values()) > 0
