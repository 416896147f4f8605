#!/usr/bin/env python3
"""Regenerate the device runtime's golden replay outputs (tests/fixtures/app/).

    .venv/bin/python tools/make_app_goldens.py            # goldens of every session
    .venv/bin/python tools/make_app_goldens.py --session  # first the fault session
    .venv/bin/python tools/make_app_goldens.py --push     # first the push session
    .venv/bin/python tools/make_app_goldens.py --video    # first the clip push session
    .venv/bin/python tools/make_app_goldens.py --only push  # only these sessions' goldens

The fault session (``faults.mcap``) is a simulated cylinder session with faults put
in: depth dropouts, a hole, a camera that stops sending for 0.6 s, a surface out of
range, and (in its metadata, raised by the replay) IMU read errors.

The push session (``push.mcap``) is a simulated session in which a host pushes new
content over the serial link while the device projects: the real host code (the
``smpclient`` client with its serial framing, ``link.client.upload`` and
``ActivateWrite``, as ``adaproj push --activate`` runs them) talks to the device's
SMP server through an in-memory line; every request's bytes are stored as
``/serial/rx`` and every reply as ``/serial/tx``, at virtual times from ``PUSH_AT_S``
(1 MB/s on the line). The pushed file's name, size and SHA-256 are in the session
metadata (key ``push``).

The clip push session (``push-clip.mcap``) is the same with a short clip (an orange
disc moving across blurred noise, :func:`push_clip`, MPEG-4 in ``.mp4``, 192x108,
2 s at 12 fps) and a mask (the band the subject moves in) pushed at ``CLIP_AT_S`` and
activated: the device plays it, looped; a tap-hold pauses it (``CLIP_PAUSE_S``) and
another resumes it (``CLIP_RESUME_S``). Metadata key ``push``: both files' names,
sizes and SHA-256, and the clip's size, rate and frame count.

The sessions' depth frames are drawn from the OAK-D's noise model (the simulator's
default). Everything is seeded, so the same command gives the same files. The tests
never write these. After a change to the depth or warp pipeline, every replay golden
(these and the session fixtures' tracking digests) is rewritten by the two commands

    .venv/bin/python tools/make_fixtures.py --golden-only
    .venv/bin/python tools/make_app_goldens.py
"""

from __future__ import annotations

import argparse
import asyncio
import hashlib
import json
import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import FAULTS_KEY, ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.geometry.calibration import Calibration  # noqa: E402
from adaproj_edge.hal.button import ButtonEvent  # noqa: E402
from adaproj_edge.hal.depth import DepthFrame  # noqa: E402
from adaproj_edge.link.device import StandaloneDevice  # noqa: E402
from adaproj_edge.link.framing import FrameDecoder, encode_frame  # noqa: E402
from adaproj_edge.link.server import Server  # noqa: E402
from adaproj_edge.link.store import ContentStore  # noqa: E402
from adaproj_edge.session import schemas  # noqa: E402
from adaproj_edge.session.hand import HandMotion  # noqa: E402
from adaproj_edge.session.records import SerialTraffic  # noqa: E402
from adaproj_edge.session.simulator import (  # noqa: E402
    HAND_KEY,
    KEY_CODE,
    SENSOR_KEY,
    T0_NS,
    Scene,
    SimulationSettings,
    hand_metadata,
    simulate,
)
from adaproj_edge.session.writer import SessionWriter  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from tests.app.golden import (  # noqa: E402
    FAULTS_SESSION,
    GOLDEN,
    PUSH_CLIP_SESSION,
    PUSH_SESSION,
    golden_view,
    session_paths,
)
from tests.content.clips import subject_frame  # noqa: E402

# (kind, start s, end s) from the start of the session
DEPTH_FAULTS = [
    ("dropout", 1.5, 1.8),
    ("hole", 1.8, 2.1),
    ("disconnect", 2.4, 3.0),
    ("range", 3.4, 3.7),
]
IMU_ERRORS = [{"kind": "imu", "start_s": 4.0, "end_s": 4.4}]


def _faulty(frame: DepthFrame) -> DepthFrame | None:
    t = (frame.sensor_ns - T0_NS) / 1e9
    for kind, a, b in DEPTH_FAULTS:
        if not a <= t < b:
            continue
        d = frame.depth_mm.copy()
        if kind == "dropout":
            d[:] = 0
        elif kind == "hole":
            d[120:260, 240:420] = 0
        elif kind == "disconnect":
            return None
        elif kind == "range":
            d[d > 0] = 9000
        return replace(frame, depth_mm=d)
    return frame


def make_fault_session() -> None:
    scene = Scene.load("cylinder-convex")
    cal = Calibration.default()
    settings = SimulationSettings(seconds=5.0, depth_fps=5.0, seed=21, presses=(0.2,))
    recs = simulate(scene, cal, settings)
    meta = {
        "source": "simulator",
        "surface": json.dumps(scene.spec),
        "seed": str(settings.seed),
        "seconds": str(settings.seconds),
        SENSOR_KEY: settings.stereo.name,
        "depth_faults": json.dumps(DEPTH_FAULTS),
        FAULTS_KEY: json.dumps(IMU_ERRORS),
    }
    FAULTS_SESSION.parent.mkdir(parents=True, exist_ok=True)
    tmp = FAULTS_SESSION.with_name(FAULTS_SESSION.name + ".part")
    with SessionWriter(tmp, cal, meta, T0_NS) as w:
        w.attach_json(schemas.TRUTH_SURFACE_ATTACHMENT, scene.spec, T0_NS)
        for r in recs:
            if isinstance(r, DepthFrame):
                r2 = _faulty(r)
                if r2 is None:
                    continue
                r = r2
            w.write(r)
    os.replace(tmp, FAULTS_SESSION)
    print(f"wrote {FAULTS_SESSION} ({FAULTS_SESSION.stat().st_size} bytes)")


PUSH_AT_S = 2.0
PUSH_NAME = "pushed.png"
LINE_NS_PER_BYTE = 1_000  # 1 MB/s
TURNAROUND_NS = 1_000_000


def push_image() -> bytes:
    """The pushed content: a blue field, a yellow disc, a noisy band (two upload chunks)."""
    rng = np.random.default_rng(5)
    img = np.zeros((150, 240, 3), np.uint8)
    img[:] = (200, 60, 20)
    cv2.circle(img, (120, 60), 45, (0, 220, 255), thickness=-1)
    img[90:, :] = rng.integers(0, 256, (60, 240, 3), dtype=np.uint8)
    ok, enc = cv2.imencode(".png", img)
    assert ok
    return bytes(enc.tobytes())


class _Line:
    """The USB serial line in memory, shaped as the pyserial object smpclient's serial
    transport writes to and reads from; the device's server answers on the other end.
    Each request's bytes (rx) and its reply (tx) are kept with virtual times."""

    port = "memory"
    out_waiting = 0

    def __init__(self, server: Server, t_ns: int) -> None:
        self.server = server
        self.decoder = FrameDecoder(server.max_message)
        self.t_ns = t_ns
        self.records: list[SerialTraffic] = []
        self._request = bytearray()
        self._reply = bytearray()

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        pass

    def write(self, data: bytes) -> int:
        self._request += data
        for message in self.decoder.feed(bytes(data)):
            rx = bytes(self._request)
            self._request.clear()
            self.t_ns += len(rx) * LINE_NS_PER_BYTE + TURNAROUND_NS
            self.records.append(SerialTraffic(self.t_ns, "rx", rx))
            reply = self.server.handle(message)
            if reply is not None:
                tx = encode_frame(reply)
                self.t_ns += len(tx) * LINE_NS_PER_BYTE + TURNAROUND_NS
                self.records.append(SerialTraffic(self.t_ns, "tx", tx))
                self._reply += tx
        return len(data)

    def read_all(self) -> bytes:
        data = bytes(self._reply)
        self._reply.clear()
        return data


def push_traffic(
    data: bytes, name: str, t_ns: int, mask: tuple[bytes, str] | None = None
) -> list[SerialTraffic]:
    """The serial traffic of ``adaproj push IMAGE --activate`` starting at ``t_ns``
    (with ``mask``, (bytes, name): the mask uploaded first and activated with it)."""
    from smpclient import SMPClient
    from smpclient.transport.serial import SMPSerialTransport

    from adaproj_edge.link import client

    class MemoryTransport(SMPSerialTransport):
        async def connect(self, address: str, timeout_s: float) -> None:
            self._reset_state()

    with tempfile.TemporaryDirectory() as tmp:
        cal = Calibration.default()
        server = Server(
            ContentStore(Path(tmp) / "store"),
            StandaloneDevice(cal.projector.width, cal.projector.height),
        )
        line = _Line(server, t_ns)
        transport = MemoryTransport()
        transport._conn = line  # type: ignore[misc]

        async def go() -> None:
            c = SMPClient(transport, "memory", timeout_s=5.0)
            await c.connect()
            if mask is not None:
                await client.upload(c, mask[0], mask[1])
            await client.upload(c, data, name)
            mask_name = None if mask is None else mask[1]
            await client.call(c, client.ActivateWrite(image=name, mask=mask_name))
            await c.disconnect()

        asyncio.run(go())
        assert (Path(tmp) / "store" / name).read_bytes() == data
    return line.records


def make_push_session() -> None:
    scene = Scene.load("cylinder-convex")
    cal = Calibration.default()
    settings = SimulationSettings(seconds=3.5, depth_fps=5.0, seed=31, presses=(0.2,))
    recs = simulate(scene, cal, settings)
    data = push_image()
    traffic = push_traffic(data, PUSH_NAME, T0_NS + int(PUSH_AT_S * 1e9))
    push = {
        "name": PUSH_NAME,
        "bytes": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
        "t_s": PUSH_AT_S,
    }
    meta = {
        "source": "simulator",
        "surface": json.dumps(scene.spec),
        "seed": str(settings.seed),
        "seconds": str(settings.seconds),
        SENSOR_KEY: settings.stereo.name,
        "push": json.dumps(push),
    }
    _write_session(PUSH_SESSION, cal, meta, scene.spec, [*recs, *traffic])
    n_rx = sum(1 for t in traffic if t.direction == "rx")
    print(
        f"wrote {PUSH_SESSION} ({PUSH_SESSION.stat().st_size} bytes; {len(data)}-byte PNG "
        f"pushed in {n_rx} requests at {PUSH_AT_S} s)"
    )


def _write_session(
    path: Path, cal: Calibration, meta: dict[str, str], spec: object, records: list[Any]
) -> None:
    """Write ``records`` (sorted by receive time) with the truth surface ``spec`` to
    ``path``, atomically (a ``.part`` file renamed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    with SessionWriter(tmp, cal, meta, T0_NS) as w:
        w.attach_json(schemas.TRUTH_SURFACE_ATTACHMENT, spec, T0_NS)
        for r in sorted(records, key=lambda r: r.receive_ns):
            w.write(r)
    os.replace(tmp, path)


CLIP_AT_S = 1.3
CLIP_NAME = "moving.mp4"
CLIP_MASK_NAME = "moving-mask.png"
CLIP_SIZE = (192, 108)
CLIP_FPS = 12.0
CLIP_FRAMES = 24
CLIP_SPEED = 4.0  # px a frame
# tap-holds: (tap at s, second press at s, released at s)
CLIP_PAUSE_S = (2.0, 2.15, 3.0)
CLIP_RESUME_S = (3.3, 3.45, 4.3)
CLIP_SECONDS = 5.6
# still 3 s (the capture, the push, a pause), 0.4 s moving, still again: few
# content-free solves (the replay's cost), most frames refined per frame
CLIP_HAND = {"still_s": 3.0, "move_s": 0.4}


def push_clip(path: Path) -> tuple[bytes, bytes]:
    """The pushed clip (written to ``path``: MPEG-4, the OpenCV wheels' encoder) and its
    mask (PNG: where the subject passes, dilated), as bytes."""
    fourcc = cv2.VideoWriter_fourcc(*"mp4v")
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, fourcc, CLIP_FPS, CLIP_SIZE)
    assert writer.isOpened()
    band = np.zeros(CLIP_SIZE[::-1], bool)
    for i in range(CLIP_FRAMES):
        img, subject = subject_frame(i, CLIP_SIZE, CLIP_SPEED)
        writer.write(img)
        band |= subject
    writer.release()
    mask = cv2.dilate(band.astype(np.uint8) * 255, np.ones((9, 9), np.uint8))
    ok, enc = cv2.imencode(".png", mask)
    assert ok
    return path.read_bytes(), bytes(enc.tobytes())


def _tap_hold(tap_s: float, press_s: float, release_s: float) -> list[ButtonEvent]:
    """A tap (100 ms), then a press held to ``release_s``: the tap-hold gesture."""
    out = []
    for t_s, pressed in ((tap_s, True), (tap_s + 0.1, False), (press_s, True), (release_s, False)):
        ts = T0_NS + round(t_s * 1e9)
        out.append(ButtonEvent(ts, ts + 1_000_000, KEY_CODE, pressed))
    return out


def make_push_clip_session() -> None:
    scene = Scene.load("cylinder-convex")
    cal = Calibration.default()
    hand = HandMotion(CLIP_SECONDS, 41, **CLIP_HAND)
    settings = SimulationSettings(
        seconds=CLIP_SECONDS, depth_fps=5.0, seed=41, presses=(0.2,), motion=hand
    )
    recs = simulate(scene, cal, settings)
    with tempfile.TemporaryDirectory() as tmp:
        clip, mask = push_clip(Path(tmp) / CLIP_NAME)
    t_ns = T0_NS + int(CLIP_AT_S * 1e9)
    traffic = push_traffic(clip, CLIP_NAME, t_ns, (mask, CLIP_MASK_NAME))
    buttons = _tap_hold(*CLIP_PAUSE_S) + _tap_hold(*CLIP_RESUME_S)
    push = {
        "name": CLIP_NAME,
        "bytes": len(clip),
        "sha256": hashlib.sha256(clip).hexdigest(),
        "mask": CLIP_MASK_NAME,
        "mask_bytes": len(mask),
        "mask_sha256": hashlib.sha256(mask).hexdigest(),
        "t_s": CLIP_AT_S,
        "size": list(CLIP_SIZE),
        "fps": CLIP_FPS,
        "frames": CLIP_FRAMES,
        "speed_px": CLIP_SPEED,
        "pause_s": CLIP_PAUSE_S[2],
        "resume_s": CLIP_RESUME_S[2],
    }
    meta = {
        "source": "simulator",
        "surface": json.dumps(scene.spec),
        "seed": str(settings.seed),
        "seconds": str(settings.seconds),
        SENSOR_KEY: settings.stereo.name,
        "push": json.dumps(push),
        HAND_KEY: json.dumps(hand_metadata(hand)),
    }
    _write_session(PUSH_CLIP_SESSION, cal, meta, scene.spec, [*recs, *traffic, *buttons])
    n_rx = sum(1 for t in traffic if t.direction == "rx")
    print(
        f"wrote {PUSH_CLIP_SESSION} ({PUSH_CLIP_SESSION.stat().st_size} bytes; "
        f"{len(clip)}-byte clip and {len(mask)}-byte mask pushed in {n_rx} requests "
        f"at {CLIP_AT_S} s)"
    )


def make_goldens(only: list[str] | None = None) -> None:
    """Replay the sessions and write their goldens; ``only``: just these, the others'
    entries are kept as they are."""
    paths = session_paths()
    unknown = set(only or ()) - set(paths)
    if unknown:
        raise SystemExit(f"no session {sorted(unknown)}; sessions: {', '.join(paths)}")
    out = json.loads(GOLDEN.read_text()) if only and GOLDEN.exists() else {}
    for name, path in paths.items():
        if only and name not in only:
            continue
        s = replay_session(path, None, ReplayOptions(score=False))
        out[name] = golden_view(s)
        print(f"{name}: {s['counters']}")
    GOLDEN.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {GOLDEN}")


def main() -> int:
    apply_thread_policy()
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--session", action="store_true", help="regenerate faults.mcap first")
    ap.add_argument("--push", action="store_true", help="regenerate push.mcap first")
    ap.add_argument("--video", action="store_true", help="regenerate push-clip.mcap first")
    ap.add_argument(
        "--only", nargs="+", metavar="NAME", help="rewrite only these sessions' goldens"
    )
    args = ap.parse_args()
    np.seterr(all="ignore")
    if args.session or not FAULTS_SESSION.exists():
        make_fault_session()
    if args.push or not PUSH_SESSION.exists():
        make_push_session()
    if args.video or not PUSH_CLIP_SESSION.exists():
        make_push_clip_session()
    make_goldens(args.only)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
