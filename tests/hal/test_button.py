"""input_event parsing and the evdev button driver on a pipe."""

from __future__ import annotations

import os
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from adaproj_edge.errors import DeviceNotFoundError, DevicePermissionError, InputError
from adaproj_edge.hal.button import (
    EV_KEY,
    EV_SYN,
    EVENT_FORMAT,
    ButtonEvent,
    EvdevButton,
    InputEvent,
    InputEventParser,
    ReplayButton,
    check_key_code,
    key_events,
)
from adaproj_edge.hal.clock import VirtualClock

S = struct.Struct(EVENT_FORMAT)


def rec(sec: int, usec: int, typ: int, code: int, value: int) -> bytes:
    return S.pack(sec, usec, typ, code, value)


events_st = st.lists(
    st.tuples(
        st.integers(0, 2**31),
        st.integers(0, 999_999),
        st.integers(0, 0x1F),
        st.integers(0, 0x2FF),
        st.integers(-(2**31), 2**31 - 1),
    ),
    max_size=20,
)


@given(events_st, st.lists(st.integers(1, 50), max_size=10))
def test_parser_any_split_gives_the_same_events(
    evs: list[tuple[int, int, int, int, int]], cuts: list[int]
) -> None:
    data = b"".join(rec(*e) for e in evs)
    p = InputEventParser()
    out: list[InputEvent] = []
    i = 0
    for c in cuts:
        out += p.feed(data[i : i + c])
        i += c
    out += p.feed(data[i:])
    assert p.pending == 0
    assert out == [InputEvent(s * 10**9 + u * 1000, t, c, v) for s, u, t, c, v in evs]


@given(st.binary(max_size=200))
def test_parser_never_fails_on_arbitrary_bytes(data: bytes) -> None:
    p = InputEventParser()
    out = p.feed(data)
    assert len(out) == len(data) // S.size and p.pending == len(data) % S.size


def test_key_events_keep_press_and_release_of_our_key() -> None:
    evs = [
        InputEvent(1, EV_KEY, 28, 1),
        InputEvent(2, EV_SYN, 0, 0),
        InputEvent(3, EV_KEY, 28, 2),  # autorepeat
        InputEvent(4, EV_KEY, 30, 1),  # another key
        InputEvent(5, EV_KEY, 28, 0),
    ]
    assert key_events(evs, 28, 9) == [ButtonEvent(1, 9, 28, True), ButtonEvent(5, 9, 28, False)]


def test_evdev_button_reads_records_from_a_pipe() -> None:
    r, w = os.pipe()
    path = f"/proc/self/fd/{r}"
    clock = VirtualClock(77)
    b = EvdevButton(path, 28, clock)
    try:
        assert b.read(0.0) is None
        data = (
            rec(10, 5, EV_KEY, 28, 1) + rec(10, 5, EV_SYN, 0, 0) + rec(10, 200_000, EV_KEY, 28, 0)
        )
        os.write(w, data[:20])
        assert b.read(0.0) is None  # half a record so far
        os.write(w, data[20:])
        assert b.read(1.0) == ButtonEvent(10_000_005_000, 77, 28, True)
        assert b.read(0.0) == ButtonEvent(10_200_000_000, 77, 28, False)
        os.close(w)
        assert b.read(0.0) is None  # end of the stream
    finally:
        b.close()
        os.close(r)


def test_missing_event_device(tmp_path: os.PathLike[str]) -> None:
    with pytest.raises(DeviceNotFoundError, match="gpio-keys"):
        EvdevButton(f"{tmp_path}/event9", 28, VirtualClock())


@pytest.mark.skipif(os.geteuid() == 0, reason="root may open anything")
def test_unreadable_event_device(tmp_path: os.PathLike[str]) -> None:
    p = f"{tmp_path}/event0"
    open(p, "wb").close()
    os.chmod(p, 0)
    with pytest.raises(DevicePermissionError):
        EvdevButton(p, 28, VirtualClock())


def test_replay_button_moves_the_virtual_clock() -> None:
    clock = VirtualClock()
    evs = [ButtonEvent(5, 10, 28, True), ButtonEvent(8, 20, 28, False)]
    b = ReplayButton(evs, clock)
    assert b.read() == evs[0] and clock.now_ns() == 10
    assert b.read() == evs[1] and clock.now_ns() == 20
    assert b.read() is None
    b.close()


def test_key_code_range() -> None:
    assert check_key_code(28) == 28
    with pytest.raises(InputError):
        check_key_code(0)
