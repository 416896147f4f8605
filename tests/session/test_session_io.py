"""Sessions: record -> read is exact, cut files replay up to the cut, replay is deterministic."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from google.protobuf import descriptor_pb2  # type: ignore[import-untyped]
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session import schemas
from adaproj_edge.session.codec import Record
from adaproj_edge.session.player import Replay
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.records import SerialTraffic, TruthPose
from adaproj_edge.session.writer import SessionWriter


def some_records(n_frames: int = 3) -> list[Record]:
    rng = np.random.default_rng(3)
    recs: list[Record] = []
    t = 1_000_000_000
    for i in range(n_frames):
        depth = rng.integers(0, 5000, (40, 64), dtype=np.uint16)
        recs.append(DepthFrame(t, t + 30_000_000, i, depth))
        for k in range(5):
            tk = t + 31_000_000 + k * 5_000_000
            a = tuple(float(x) for x in rng.normal(size=3))
            g = tuple(float(x) for x in rng.normal(size=3))
            recs.append(ImuSample(tk, tk + 1000, a, g, 30.25))  # type: ignore[arg-type]
            recs.append(TruthPose(tk, (0.1 * i, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
        recs.append(ButtonEvent(t + 60_000_000, t + 61_000_000, 28, i % 2 == 0))
        recs.append(SerialTraffic(t + 62_000_000, "rx", bytes(range(i, i + 9))))
        recs.append(SerialTraffic(t + 63_000_000, "tx", b"\x00\xff" * i))
        t += 66_000_000
    return recs


def write(path: Path, recs: list[Record]) -> None:
    with SessionWriter(path, Calibration.default(), {"source": "test"}) as w:
        for r in recs:
            w.write(r)


def test_record_then_read_is_exact(tmp_path: Path) -> None:
    recs = some_records()
    write(tmp_path / "s.mcap", recs)
    s = read_session(tmp_path / "s.mcap")
    assert s.records == recs
    assert not s.truncated
    assert s.metadata["session"] == {"source": "test"}
    assert np.array_equal(s.calibration.T_P_D, Calibration.default().T_P_D)
    assert [f.sequence for f in s.depth] == [0, 1, 2]


def test_depth_is_a_foxglove_raw_image(tmp_path: Path) -> None:
    write(tmp_path / "s.mcap", some_records(1))
    with open(tmp_path / "s.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        (ch,) = [c for c in summary.channels.values() if c.topic == schemas.DEPTH]
        schema = summary.schemas[ch.schema_id]
        assert (schema.name, schema.encoding, ch.message_encoding) == (
            "foxglove.RawImage",
            "protobuf",
            "protobuf",
        )
        fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
        assert "foxglove/RawImage.proto" in [f.name for f in fds.file]
        names = [a.name for a in reader.iter_attachments()]
        assert schemas.CALIBRATION_ATTACHMENT in names


def test_replay_devices_and_clock(tmp_path: Path) -> None:
    recs = some_records()
    write(tmp_path / "s.mcap", recs)
    r = Replay(tmp_path / "s.mcap")
    cam = r.depth_camera()
    f0 = cam.read()
    assert f0 == recs[0] and r.clock.now_ns() == recs[0].receive_ns
    imu = r.imu()
    assert imu.read() == recs[1]
    button = r.button()
    ev = button.read()
    assert isinstance(ev, ButtonEvent) and r.clock.now_ns() == ev.receive_ns
    r2 = Replay(tmp_path / "s.mcap")
    times = [(type(e).__name__, r2.clock.now_ns()) for e in r2.events()]
    want, t = [], 0
    for e in recs:  # the virtual clock never goes back
        t = max(t, e.receive_ns)
        want.append((type(e).__name__, t))
    assert times == want


def test_not_a_session(tmp_path: Path) -> None:
    (tmp_path / "x.mcap").write_bytes(b"hello world, not mcap")
    with pytest.raises(InputError, match="not an MCAP"):
        read_session(tmp_path / "x.mcap")
    with pytest.raises(InputError, match="not found"):
        read_session(tmp_path / "none.mcap")


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, list[Record]]:
    path = tmp_path_factory.mktemp("cut") / "s.mcap"
    recs = some_records(6)
    # flush after every frame, as the recorder does once a second
    with SessionWriter(path, Calibration.default()) as w:
        for r in recs:
            w.write(r)
            if isinstance(r, SerialTraffic) and r.direction == "tx":
                w.flush()
    return path.read_bytes(), recs


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(cut=st.floats(0.0, 1.0))
def test_a_cut_session_replays_up_to_the_cut(
    whole: tuple[bytes, list[Record]], cut: float, tmp_path: Path
) -> None:
    data, recs = whole
    n = int(cut * len(data))
    p = tmp_path / f"cut-{n}.mcap"
    p.write_bytes(data[:n])
    try:
        s = read_session(p)
    except InputError as e:
        assert "calibration" in str(e) or "not an MCAP" in str(e)
        return
    assert s.records == recs[: len(s.records)]
    assert s.truncated == (n < len(data))


def test_power_loss_keeps_the_flushed_part(
    whole: tuple[bytes, list[Record]], tmp_path: Path
) -> None:
    data, recs = whole
    p = tmp_path / "cut.mcap"
    p.write_bytes(data[: int(0.8 * len(data))])
    s = read_session(p)
    assert s.truncated and len(s.depth) >= 3
    assert s.records == recs[: len(s.records)]
