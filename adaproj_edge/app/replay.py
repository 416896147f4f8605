"""``adaproj replay``: the runtime fed from a recorded session, on a virtual clock.

Every record is handed to the same :class:`~adaproj_edge.app.runtime.Runtime` the
device runs, in recorded order, with :meth:`Runtime.tick` before each, and the
projected frames go to an in-memory display. Nothing waits on the wall clock, so a
replay makes the same decisions every time and runs as fast as the pipeline.

Faults that a session file cannot hold as data (an IMU read that raises, a camera
that raises) are listed in the session's metadata (``session`` record, key
``app_faults``: JSON list of ``{"kind": "imu" | "camera", "start_s", "end_s"}``,
seconds from the first record); the replay raises them at the device boundary.

With the session's ground truth (simulated sessions) each content-aware frame is
scored: the distortion of the displayed map on the true surface at the true pose of
that moment, next to the distortion of the warp computed from the true surface.

Serial traffic (``/serial/rx``, ``/serial/tx``) goes through the device's own SMP
:class:`~adaproj_edge.link.server.Server`, with the runtime as its content sink and a
content store of its own (``OUT/store``, or a temporary directory): each recorded
``rx`` chunk is decoded and answered at its recorded time, on the replay's thread, so
a content push recorded mid-session switches the content at the same point. What the
server answers is compared, reply by reply, with the recorded ``tx``; a difference is
counted in the summary (``link``), not an error. Bad bytes are logged and dropped, as
on the device.
"""

from __future__ import annotations

import json
import logging
import os
import resource
import shutil
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from adaproj_edge.app.memory import pin_mmap_threshold
from adaproj_edge.app.pipeline import WarpPipeline
from adaproj_edge.app.runtime import AppSettings, Item, Runtime, mask_content_map
from adaproj_edge.arrays import Image
from adaproj_edge.content.builtin import poster, poster_mask
from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.link.framing import FrameDecoder
from adaproj_edge.link.message import parse_header
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore
from adaproj_edge.render.sheet import row, stack
from adaproj_edge.session import schemas
from adaproj_edge.session.player import Replay
from adaproj_edge.session.reader import Scan, iter_records
from adaproj_edge.session.records import SerialTraffic, TruthPose
from adaproj_edge.session.simulator import (
    Scene,
    scene_of_session,
    scoring_projector,
    true_surface,
)
from adaproj_edge.warp.engine import WarpSettings, compute_warp
from adaproj_edge.warp.quality import measure

log = logging.getLogger(__name__)

FAULTS_KEY = "app_faults"
SAMPLE_FRAMES = 12
LISTED_MISMATCHES = 10


@dataclass(frozen=True)
class InjectedFault:
    """A device that raises between ``start_s`` and ``end_s`` (session seconds)."""

    kind: str
    start_s: float
    end_s: float

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s < self.end_s


@dataclass(frozen=True)
class ReplayOptions:
    settings: AppSettings = field(default_factory=AppSettings)
    all_frames: bool = False
    score: bool = True
    # replaces the session's calibration (its depth model stays the session's)
    calibration: Calibration | None = None


def builtin_item(threshold: float = DEFAULT_THRESHOLD) -> Item:
    """The built-in poster with its mask as content map (no saliency model needed)."""
    img = poster()
    return Item("poster", img, mask_content_map(img, poster_mask(), threshold))


def session_faults(metadata: dict[str, dict[str, str]]) -> list[InjectedFault]:
    raw = metadata.get("session", {}).get(FAULTS_KEY)
    if raw is None:
        return []
    try:
        return [
            InjectedFault(str(f["kind"]), float(f["start_s"]), float(f["end_s"]))
            for f in json.loads(raw)
        ]
    except (ValueError, KeyError, TypeError) as e:
        raise InputError(f"session metadata {FAULTS_KEY} is malformed: {e}") from None


def rss_mb() -> float:
    """Current resident set size (Linux), in MB."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e6
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3


class _Frames:
    """Frames the runtime showed: an evenly spaced sample (PNG in memory, bounded),
    and every frame written to ``out/frames`` on request."""

    def __init__(self, out: Path | None, all_frames: bool) -> None:
        self.out = out
        self.all = all_frames
        self.sample: list[tuple[int, int, bytes, Image, str]] = []
        self.stride = 1
        self.count = 0
        self.checksums: list[dict[str, Any]] = []
        self.t0 = 0

    def __call__(self, t_ns: int, frame: Image, info: dict[str, Any]) -> None:
        self.count += 1
        faults = info["faults"]
        caption = f"{(t_ns - self.t0) / 1e9:.2f}s {info['kind']}"
        caption += " [" + ",".join(faults) + "]" if faults else ""
        mean = [round(float(x), 2) for x in cv2.mean(frame)[:3]]
        self.checksums.append(
            {"t_ns": t_ns, "kind": info["kind"], "mean_bgr": mean, "faults": faults}
        )
        if self.out is not None and self.all:
            cv2.imwrite(str(self.out / "frames" / f"{self.count:05d}.png"), frame)
        if (self.count - 1) % self.stride:
            return
        _, png = cv2.imencode(".png", frame)
        small = cv2.resize(
            frame, (frame.shape[1] // 4, frame.shape[0] // 4), interpolation=cv2.INTER_AREA
        )
        self.sample.append(
            (self.count, t_ns, bytes(png.tobytes()), np.asarray(small, np.uint8), caption)
        )
        if len(self.sample) > 2 * SAMPLE_FRAMES:
            self.stride *= 2
            self.sample = [x for x in self.sample if (x[0] - 1) % self.stride == 0]

    def picked(self) -> list[tuple[int, int, bytes, Image, str]]:
        n = len(self.sample)
        if n <= SAMPLE_FRAMES:
            return self.sample
        idx = np.unique(np.linspace(0, n - 1, SAMPLE_FRAMES).round().astype(int))
        return [self.sample[i] for i in idx]


class _Scorer:
    """Distortion on the true surface: displayed map vs the warp from the truth."""

    def __init__(self, scene: Scene, runtime: Runtime, attachments: dict[str, bytes]) -> None:
        self.scene = scene
        self.rt = runtime
        # the projector that really lights the surface (a simulated session's true rig)
        self.projector = scoring_projector(attachments, runtime.calibration.projector)
        self.pipeline = WarpPipeline(
            runtime.calibration.projector, runtime.settings.grid, runtime.settings.map_scale
        )
        self.scores: list[dict[str, Any]] = []

    def score(self, pose: TruthPose) -> None:
        rt = self.rt
        item = rt.item
        if rt.shown_map is None or item.content_map is None:
            return
        truth = true_surface(self.scene, pose, self.projector, (101, 161))
        settings = WarpSettings(
            mode="content", grid=rt.settings.grid, threshold=item.settings.threshold
        )
        # the engine's warp on the true surface: full grid, full refinement
        ref_map = self.pipeline.display_map(
            compute_warp(truth, item.size, item.content_map, settings)
        )
        salient = item.content_map.full_size() >= item.content_map.threshold
        shown, shown_s = measure(rt.shown_map, truth, salient)
        ref, ref_s = measure(ref_map, truth, salient)
        assert shown_s is not None and ref_s is not None
        self.scores.append(
            {
                "t_ns": rt.clock.now_ns(),
                "shown_angle_error": round(shown.angle_error, 5),
                "truth_angle_error": round(ref.angle_error, 5),
                "shown_size_inconsistency": round(shown.size_inconsistency, 5),
                "truth_size_inconsistency": round(ref.size_inconsistency, 5),
                "shown_salient_angle_error": round(shown_s.angle_error, 5),
                "truth_salient_angle_error": round(ref_s.angle_error, 5),
            }
        )


class _Link:
    """The device's SMP server on the recorded serial bytes, driven from the replay loop.

    The server (and its store) is made at the first ``rx`` chunk, so a session
    without serial traffic leaves no store behind.
    """

    def __init__(self, store_root: Path, runtime: Runtime) -> None:
        self.store_root = store_root
        self.rt = runtime
        self.server: Server | None = None
        self.decoder: FrameDecoder | None = None
        self.recorded = FrameDecoder(0xFFFF - 2)
        self.replies: list[tuple[int, bytes]] = []
        self.recorded_replies: list[bytes] = []
        self.rx_bytes = 0
        self.tx_bytes = 0

    def _open(self) -> tuple[Server, FrameDecoder]:
        if self.server is None or self.decoder is None:
            self.server = Server(ContentStore(self.store_root), self.rt)
            self.server.on_reset = self.server.restore_active
            self.decoder = FrameDecoder(self.server.max_message)
        return self.server, self.decoder

    def feed(self, rec: SerialTraffic) -> None:
        if rec.direction == "tx":
            self.tx_bytes += len(rec.data)
            self.recorded_replies.extend(self.recorded.feed(rec.data))
            return
        if rec.direction != "rx":
            log.warning("ignored serial bytes with direction %r", rec.direction)
            return
        self.rx_bytes += len(rec.data)
        server, decoder = self._open()
        for message in decoder.feed(rec.data):
            reply = server.handle(message)
            if reply is not None:
                self.replies.append((rec.receive_ns, reply))
            if server.after_reply is not None:
                server.after_reply()

    def summary(self, t0: int) -> dict[str, Any]:
        got = self.replies
        want = self.recorded_replies
        mismatches: list[dict[str, Any]] = []
        n_bad = abs(len(got) - len(want))
        for i, ((t_ns, reply), recorded) in enumerate(zip(got, want, strict=False)):
            if reply == recorded:
                continue
            n_bad += 1
            if len(mismatches) < LISTED_MISMATCHES:
                _, _, _, _, group, seq, cmd = parse_header(reply)
                mismatches.append(
                    {"reply": i, "t_s": _rel(t_ns, t0), "group": group, "command": cmd, "seq": seq}
                )
        counters = dict(self.server.counters) if self.server is not None else {}
        dropped = dict(self.decoder.stats.dropped) if self.decoder is not None else {}
        return {
            "rx_bytes": self.rx_bytes,
            "tx_bytes": self.tx_bytes,
            "requests": counters.get("requests", 0),
            "refused": counters.get("errors", 0),
            "ignored": counters.get("ignored", 0),
            "dropped_frames": dropped,
            "content_activations": sum(
                1 for e in self.rt.events if e["event"] == "content" and e.get("source") == "link"
            ),
            "replies": len(got),
            "recorded_replies": len(want),
            "tx_mismatches": n_bad,
            "mismatched": mismatches,
        }


def replay_session(
    path: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    options: ReplayOptions | None = None,
) -> dict[str, Any]:
    """Replay ``path`` through the runtime; write frames, summary and contact sheet to
    ``out`` (when given; the link's content store goes to ``out/store``, emptied
    first); return the summary."""
    options = options or ReplayOptions()
    pin_mmap_threshold()
    path = Path(path)
    replay = Replay(path)
    scan = Scan()
    for _ in iter_records(path, topics=set(), scan=scan):
        pass
    faults = session_faults(scan.metadata)
    out_dir = Path(out) if out is not None else None
    if out_dir is not None:
        (out_dir / "frames").mkdir(parents=True, exist_ok=True)
        shutil.rmtree(out_dir / "store", ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="adaproj-replay-") as tmp:
        store = out_dir / "store" if out_dir is not None else Path(tmp) / "store"
        summary, frames = _replay(path, replay, scan, faults, out_dir, store, options)
    if out_dir is not None:
        _write(out_dir, summary, frames)
    return summary


def _replay(
    path: Path,
    replay: Replay,
    scan: Scan,
    faults: list[InjectedFault],
    out_dir: Path | None,
    store: Path,
    options: ReplayOptions,
) -> tuple[dict[str, Any], _Frames]:
    frames = _Frames(out_dir, options.all_frames)
    cal = replay.calibration
    if options.calibration is not None:
        cal = options.calibration.with_depth(cal.depth)
    display = MemoryDisplay(cal.projector.width, cal.projector.height)
    settings = replace(options.settings, keep_shown_map=options.score)
    rt = Runtime(cal, display, replay.clock, [builtin_item()], settings, mask_content_map, frames)
    link = _Link(store, rt)
    scorer = None
    spec_raw = scan.attachments.get(schemas.TRUTH_SURFACE_ATTACHMENT)
    if options.score and spec_raw is not None:
        scene = scene_of_session(json.loads(spec_raw), scan.attachments)
        scorer = _Scorer(scene, rt, scan.attachments)
    t0: int | None = None
    rss: list[float] = []
    pose: TruthPose | None = None
    scored = 0
    n_records = 0
    for rec in replay.events():
        n_records += 1
        if t0 is None:
            t0 = rec.receive_ns
            frames.t0 = t0
            rt.boot()
        t_s = (rec.receive_ns - t0) / 1e9
        rt.tick()
        if isinstance(rec, ImuSample):
            if any(f.kind == "imu" and f.active(t_s) for f in faults):
                rt.on_imu_error("IMU read failed: [Errno 5] Input/output error (injected)")
            else:
                rt.on_imu(rec)
        elif isinstance(rec, DepthFrame):
            if any(f.kind == "camera" and f.active(t_s) for f in faults):
                rt.on_depth_error("the OAK-D stopped sending depth (injected disconnect)")
            else:
                rt.on_depth(rec)
                if scorer is not None and pose is not None and rt.update_count > scored:
                    scored = rt.update_count
                    if rt.updates[-1]["kind"] == "content-aware":
                        scorer.score(pose)
        elif isinstance(rec, ButtonEvent):
            rt.on_button(rec)
        elif isinstance(rec, TruthPose):
            pose = rec
        elif isinstance(rec, SerialTraffic):
            link.feed(rec)
        if n_records % 200 == 0:
            rss.append(round(rss_mb(), 1))
    if t0 is None:
        raise InputError(f"session {path} holds no records")
    rt.tick()
    rss.append(round(rss_mb(), 1))
    summary = _summary(path, rt, frames, faults, scorer, rss, t0)
    summary["link"] = link.summary(t0)
    if summary["link"]["rx_bytes"]:
        log.info("link: %s", {k: v for k, v in summary["link"].items() if k != "mismatched"})
    return summary, frames


def _rel(t_ns: int, t0: int) -> float:
    return round((t_ns - t0) / 1e9, 4)


def _timed(items: Iterable[dict[str, Any]], t0: int) -> list[dict[str, Any]]:
    """``items`` with ``t_ns`` replaced by ``t_s``, seconds from the session start."""
    return [
        {"t_s": _rel(x["t_ns"], t0), **{k: v for k, v in x.items() if k != "t_ns"}} for x in items
    ]


def _summary(
    path: Path,
    rt: Runtime,
    frames: _Frames,
    faults: list[InjectedFault],
    scorer: _Scorer | None,
    rss: list[float],
    t0: int,
) -> dict[str, Any]:
    lat = np.asarray(rt.latencies_ms)
    return {
        "session": path.name,
        "duration_s": _rel(rt.clock.now_ns(), t0),
        "states": [[_rel(t, t0), s] for t, s in rt.states],
        "events": _timed(rt.events, t0),
        "counters": dict(rt.counters),
        "updates": _timed(rt.updates, t0),
        "frames": _timed(frames.checksums, t0),
        "injected_faults": [f.__dict__ for f in faults],
        "timings_ms": rt.pipeline.times.summary(),
        "motion_to_frame_ms": {
            "n": int(lat.size),
            "median": round(float(np.median(lat)), 2) if lat.size else None,
            "p95": round(float(np.percentile(lat, 95)), 2) if lat.size else None,
        },
        "distortion": [] if scorer is None else _timed(scorer.scores, t0),
        "rss_mb": rss,
    }


def _write(out: Path, summary: dict[str, Any], frames: _Frames) -> None:
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    picked = frames.picked()
    for n, t_ns, png, _, _ in picked:
        name = f"sample_{n:05d}_{(t_ns - frames.t0) / 1e9:07.3f}s.png"
        (out / "frames" / name).write_bytes(png)
    if picked:
        rows = [
            row([p[3] for p in picked[i : i + 4]], [p[4] for p in picked[i : i + 4]], 200)
            for i in range(0, len(picked), 4)
        ]
        cv2.imwrite(str(out / "contact_sheet.png"), stack(rows))
