"""Sessions damaged on the card: sizes that lie, chunks that inflate, flipped bits.

The reader checks every declared size against the file, inflates a chunk only up to
what it declares (and at most ``MAX_CHUNK``), skips a damaged chunk with a message that
says so and goes on with the next good one.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from adaproj_edge.errors import InputError
from adaproj_edge.session.reader import Scan, iter_records, read_session
from tests.session.damage import chunks, flip, inflating_chunk, layout, lying_attachment

SESSION = Path(__file__).parents[1] / "fixtures" / "sessions" / "sphere.mcap"
REPLAY = (sys.executable, "-m", "adaproj_edge.cli", "replay")
READER_MB = 300
"""Peak resident memory of a process reading any session (it imports numpy, OpenCV)."""


@pytest.fixture(scope="module")
def whole() -> tuple[bytes, list[object]]:
    return SESSION.read_bytes(), read_session(SESSION).records


def peak_mb_of_reading(path: Path) -> tuple[float, str]:
    """Peak resident memory (MiB, from /proc) of a process reading ``path`` whole, and
    what it printed."""
    code = (
        "import sys\n"
        "from adaproj_edge.errors import InputError\n"
        "from adaproj_edge.session.reader import Scan, iter_records\n"
        "scan = Scan()\n"
        "try:\n"
        "    n = sum(1 for _ in iter_records(sys.argv[1], scan=scan))\n"
        "    print(n, scan.damage())\n"
        "except InputError as e:\n"
        "    print('refused:', e)\n"
        "for line in open('/proc/self/status'):\n"
        "    if line.startswith('VmHWM:'):\n"
        "        print(int(line.split()[1]) // 1024)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    *said, peak = out.stdout.strip().splitlines()
    return float(peak), "\n".join(said)


def test_an_attachment_declaring_2_62_bytes_is_damage_not_a_crash(tmp_path: Path) -> None:
    p = tmp_path / "lying.mcap"
    p.write_bytes(lying_attachment(2**62))
    assert len(p.read_bytes()) < 120
    scan = Scan()
    assert list(iter_records(p, scan=scan)) == []
    assert scan.damaged_count == 1 and "malformed record" in (scan.damage() or "")
    replay = subprocess.run(
        [*REPLAY, str(p), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert replay.returncode == 2, replay.stderr
    assert "Traceback" not in replay.stderr and "MemoryError" not in replay.stderr
    assert "calibration" in replay.stderr


def test_a_chunk_that_inflates_past_its_bound_is_skipped_in_bounded_memory(
    tmp_path: Path,
) -> None:
    p = tmp_path / "inflating.mcap"
    inflating_chunk(p, 2**30)  # 32 KB on the card, a gigabyte inflated
    peak, said = peak_mb_of_reading(p)
    assert said.startswith("0 ") and "too large" in said, said
    assert peak < READER_MB, f"reading peaked at {peak:.0f} MB"


def test_a_flipped_bit_in_a_chunk_loses_that_chunk_only(
    whole: tuple[bytes, list[object]], tmp_path: Path
) -> None:
    data, records = whole
    at, n = chunks(data)[len(chunks(data)) // 2]
    p = tmp_path / "flipped.mcap"
    p.write_bytes(flip(data, 8 * (at + 9 + n // 2)))
    s = read_session(p)
    assert 0 < len(s.records) < len(records)
    assert all(r in records for r in s.records[:10])
    assert s.records[-1] == records[-1]  # read on to the end
    scan = Scan()
    for _ in iter_records(p, scan=scan):
        pass
    said = scan.damage() or ""
    assert scan.damaged_count == 1 and "damaged part" in said and "cut short" not in said
    assert scan.complete and not scan.truncated


@pytest.mark.parametrize("field", ["opcode", "length"])
def test_a_damaged_record_header_is_skipped_to_the_next_good_chunk(
    whole: tuple[bytes, list[object]], tmp_path: Path, field: str
) -> None:
    data, records = whole
    at, _ = chunks(data)[3]
    bit = 8 * at if field == "opcode" else 8 * (at + 1) + 60  # the length's high bits
    p = tmp_path / "header.mcap"
    p.write_bytes(flip(data, bit))
    scan = Scan()
    got = list(iter_records(p, scan=scan))
    assert got[-1] == records[-1] and 0 < len(got) < len(records)
    assert scan.complete and scan.damaged_count >= 1
    assert "cut short" not in (scan.damage() or "")


def test_a_cut_session_still_says_it_is_cut(
    whole: tuple[bytes, list[object]], tmp_path: Path
) -> None:
    data, _ = whole
    _op, at, n = layout(data)[len(layout(data)) // 2]
    p = tmp_path / "cut.mcap"
    p.write_bytes(data[: at + 9 + n // 2])
    scan = Scan()
    for _ in iter_records(p, scan=scan):
        pass
    assert scan.truncated and "cut short" in (scan.damage() or "")
    assert scan.damaged_count == 0


def test_replay_goes_on_after_a_damaged_chunk(
    whole: tuple[bytes, list[object]], tmp_path: Path
) -> None:
    data, _ = whole
    at, n = chunks(data)[2]
    p = tmp_path / "flipped.mcap"
    p.write_bytes(flip(data, 8 * (at + 9 + n // 2)))
    replay = subprocess.run(
        [*REPLAY, str(p), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert replay.returncode == 0, replay.stderr[-2000:]
    assert "damaged part(s) skipped" in replay.stderr and "cut short" not in replay.stderr


def test_not_an_mcap_file_is_still_refused(tmp_path: Path) -> None:
    p = tmp_path / "x.mcap"
    p.write_bytes(b"\x89MCAP0\r\n")
    with pytest.raises(InputError, match="not an MCAP"):
        read_session(p)
