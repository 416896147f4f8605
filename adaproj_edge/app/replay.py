"""``adaproj replay``: the runtime fed from a recorded session, on a virtual clock.

Every record is handed to the same :class:`~adaproj_edge.app.runtime.Runtime` the
device runs, in recorded order, through the same dispatcher
(:func:`~adaproj_edge.app.inputs.feed`), with :meth:`Runtime.tick` before each; the
projected frames go to an in-memory display. Nothing waits on the wall clock, so a
replay makes the same decisions every time and runs as fast as the pipeline.

Faults that a session file cannot hold as data (an IMU read that raises, a camera that
raises) are listed in the session's metadata (``session`` record, key ``app_faults``:
JSON list of ``{"kind": "imu" | "camera", "start_s", "end_s"}``, seconds from the first
record); the replay turns them into the device's fault inputs.

With the session's ground truth (simulated sessions) each content-aware frame is
scored (:mod:`adaproj_edge.app.scoring`). Serial traffic goes through the device's own
SMP server (:mod:`adaproj_edge.app.link_replay`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.inputs import Input, SourceFault, feed
from adaproj_edge.app.link_replay import LinkReplay
from adaproj_edge.app.memory import pin_mmap_threshold, rss_mb
from adaproj_edge.app.report import (
    FrameSampler,
    clear_outputs,
    summary,
    timed,
    write_outputs,
)
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.app.scoring import MEASURES, Scorer, SideViews
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.errors import InputError
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session import schemas
from adaproj_edge.session.player import Replay
from adaproj_edge.session.reader import Scan, iter_records
from adaproj_edge.session.records import SerialTraffic, TruthPose
from adaproj_edge.session.simulator import scene_of_session

log = logging.getLogger(__name__)

FAULTS_KEY = "app_faults"
FAULT_SOURCES = {"imu": "imu", "camera": "depth"}
"""Injected fault kind -> the failing source."""
FAULT_MESSAGES = {
    "imu": "IMU read failed: [Errno 5] Input/output error (injected)",
    "camera": "the OAK-D stopped sending depth (injected disconnect)",
}


@dataclass(frozen=True)
class InjectedFault:
    """A device that raises between ``start_s`` and ``end_s`` (session seconds)."""

    kind: str
    start_s: float
    end_s: float

    def active(self, t_s: float) -> bool:
        """Whether the fault is on at ``t_s``."""
        return self.start_s <= t_s < self.end_s


@dataclass(frozen=True)
class ReplayOptions:
    """How to replay: the runtime's settings, every frame or a sample, scoring."""

    settings: AppSettings = field(default_factory=AppSettings)
    all_frames: bool = False
    score: bool = True
    side_views: bool = True  # a few moments seen from the side, in the contact sheet


def session_faults(metadata: dict[str, dict[str, str]]) -> list[InjectedFault]:
    """The injected faults listed in a session's metadata."""
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


def _injected(rec: Input, faults: list[InjectedFault], t_s: float) -> Input:
    """``rec``, or the fault its device raises at ``t_s`` instead of delivering it."""
    kind = "imu" if isinstance(rec, ImuSample) else "camera" if isinstance(rec, DepthFrame) else ""
    if kind and any(f.kind == kind and f.active(t_s) for f in faults):
        return SourceFault(FAULT_SOURCES[kind], FAULT_MESSAGES[kind])
    return rec


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
    damage = scan.damage()
    if damage is not None:
        log.warning("%s: %s", path.name, damage)
    out_dir = Path(out) if out is not None else None
    if out_dir is not None:
        clear_outputs(out_dir)
        shutil.rmtree(out_dir / "store", ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="adaproj-replay-") as tmp:
        store = out_dir / "store" if out_dir is not None else Path(tmp) / "store"
        result, frames = _replay(path, replay, scan, faults, out_dir, store, options)
    if out_dir is not None:
        write_outputs(out_dir, result, frames)
    return result


def _replay(
    path: Path,
    replay: Replay,
    scan: Scan,
    faults: list[InjectedFault],
    out_dir: Path | None,
    store: Path,
    options: ReplayOptions,
) -> tuple[dict[str, Any], FrameSampler]:
    frames = FrameSampler(out_dir, options.all_frames)
    cal = replay.calibration
    display = MemoryDisplay(cal.projector.width, cal.projector.height)
    settings = replace(options.settings, keep_shown_map=options.score)
    rt = Runtime(cal, display, replay.clock, [builtin_item()], settings, mask_content_map, frames)
    link = LinkReplay(store, rt)
    scorer = None
    side = SideViews(rt) if options.side_views and out_dir is not None else None
    spec_raw = scan.attachments.get(schemas.TRUTH_SURFACE_ATTACHMENT)
    if options.score and spec_raw is not None:
        scorer = Scorer(scene_of_session(json.loads(spec_raw), scan.attachments), rt)
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
        rt.tick()
        if isinstance(rec, DepthFrame | ImuSample | ButtonEvent):
            feed(rt, _injected(rec, faults, (rec.receive_ns - t0) / 1e9))
            telemetry = rt.telemetry
            if isinstance(rec, DepthFrame) and telemetry.update_count > scored:
                scored = telemetry.update_count
                if telemetry.updates[-1]["kind"] == "content-aware":
                    _score(rt, scorer, side, pose)
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
    pictures = [] if side is None else side.pictures(t0)
    result = summary(
        path.name,
        rt.telemetry,
        rt.clock.now_ns(),
        frames,
        t0,
        session_file=scan.report(),
        injected_faults=[f.__dict__ for f in faults],
        distortion=[] if scorer is None else timed(scorer.scores, t0),
        distortion_measures=MEASURES,
        rss_mb=rss,
        link=link.summary(t0),
    )
    if result["link"]["rx_bytes"]:
        log.info("link: %s", {k: v for k, v in result["link"].items() if k != "mismatched"})
    frames.side_views = pictures
    return result, frames


def _score(
    rt: Runtime, scorer: Scorer | None, side: SideViews | None, pose: TruthPose | None
) -> None:
    """After a content-aware update: score it on the truth, offer it to the side views
    (on the true surface when the session has it, else on the device's estimate)."""
    if scorer is not None and pose is not None:
        scorer.score(pose)
        if side is not None and scorer.last_truth is not None:
            side.offer(scorer.last_truth, truth=True)
    elif side is not None and scorer is None and rt.surface is not None:
        side.offer(rt.surface, truth=False)
