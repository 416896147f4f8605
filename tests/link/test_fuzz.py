"""Property-based fuzzing of the decoder, the dispatcher, and what a hostile host and a
damaged card found: JPEG fill bytes, bursts of distinct refusals, pending uploads that
fill the quota, typed state files and a host that hangs up (a few thousand inputs).

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
    active_records,
    dispatch_target,
    hangup_target,
    hangups,
    jpeg_target,
    jpegs,
    messages,
    pending_floods,
    pending_target,
    refusal_bursts,
    refusals_target,
    resync_target,
    resyncs,
    state_target,
    streams,
    wire_target,
)
from tests.link.media import png_bytes

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


SMALL = settings(FUZZ, max_examples=200)


def test_jpeg_headers_are_read_as_the_decoder_reads_them() -> None:
    seen: Counter[str] = Counter()

    @SMALL
    @given(jpegs())
    def run(data: bytes) -> None:
        jpeg_target(data, seen)

    run()
    assert seen["decoded"] > 50


def test_bursts_of_distinct_refusals_stay_bounded(tmp_path: Path) -> None:
    server = make_server(tmp_path / "store")
    seen: Counter[str] = Counter()

    @SMALL
    @given(refusal_bursts())
    def run(burst: list[tuple[int, int]]) -> None:
        refusals_target(server, burst, seen)

    run()
    assert seen["refused"] > 10_000


def test_abandoned_uploads_never_keep_a_new_one_out(tmp_path: Path) -> None:
    server = make_server(tmp_path / "store")
    png = png_bytes(150, 100, seed=11)
    seen: Counter[str] = Counter()

    @settings(SMALL, max_examples=50)  # each case fsyncs a dozen files
    @given(pending_floods())
    def run(flood: list[tuple[str, int, int]]) -> None:
        pending_target(server, flood, png, seen)

    run()
    assert seen["fitted"] == 50


def test_any_saved_active_record_lets_the_server_start(tmp_path: Path) -> None:
    root = tmp_path / "store"
    root.mkdir()
    (root / "a.png").write_bytes(png_bytes(64, 40, seed=12))
    seen: Counter[str] = Counter()

    @SMALL
    @given(active_records)
    def run(record: bytes) -> None:
        state_target(root, record, seen)

    run()
    assert seen["started"] == 200


def test_a_host_hanging_up_anywhere_never_ends_the_server(tmp_path: Path) -> None:
    server = make_server(tmp_path / "store")
    seen: Counter[str] = Counter()

    @SMALL
    @given(hangups())
    def run(case: tuple[list[bytes | None], list[bool]]) -> None:
        hangup_target(server, case, seen)

    run()
    assert seen["survived"] == 200
