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

The projector's refreshes are generated on the virtual clock between the records
(every ``1 / refresh_hz`` from the first record; each computed ``lead_s`` before its
sync, from the records received by then): the display loop shows the last frame,
stabilised (:mod:`adaproj_edge.app.display_loop`), its compute time measured and the
wait for the sync modelled, so the decisions and the frames stay the same on any
machine.

With the session's ground truth (simulated sessions) each content-aware frame is
scored (:mod:`adaproj_edge.app.scoring`) and every refresh is followed onto the true
surface (:mod:`adaproj_edge.app.handheld`: jitter, drift, upright; ``handheld.png``
shows the content's motion with stabilisation on and off). Serial traffic goes
through the device's own SMP server (:mod:`adaproj_edge.app.link_replay`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from adaproj_edge.app.content import builtin_item, mask_content_map
from adaproj_edge.app.display_loop import refresh_summary
from adaproj_edge.app.handheld import HandheldScorer
from adaproj_edge.app.inputs import Input, SourceFault, feed
from adaproj_edge.app.link_replay import LinkReplay
from adaproj_edge.app.memory import pin_mmap_threshold, rss_mb
from adaproj_edge.app.motion_plot import motion_plot
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
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import MemoryDisplay
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session import schemas
from adaproj_edge.session.player import Replay
from adaproj_edge.session.reader import Scan, iter_records
from adaproj_edge.session.records import SerialTraffic, TruthPose
from adaproj_edge.session.simulator import HAND_KEY, scene_of_session, scoring_projector

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
    # with score: each content-aware update's distortion on the truth too (False: the
    # hand-held measures only, a third of a simulated session's replay the cheaper)
    distortion: bool = True
    side_views: bool = True  # a few moments seen from the side, in the contact sheet
    stabilise: bool = True  # False: the display loop shows frames as rendered (margin 0)
    # replaces the session's calibration (its depth model stays the session's)
    calibration: Calibration | None = None
    # stage times in CPU seconds of the process (``time.process_time``) instead of
    # wall-clock: benchmarks on a machine other work shares
    cpu_times: bool = False

    def app_settings(self) -> AppSettings:
        """The runtime's settings for this replay."""
        s = replace(self.settings, keep_shown_map=self.score and self.distortion)
        if not self.stabilise:
            d = s.display
            s = replace(s, display=replace(d, stabiliser=replace(d.stabiliser, margin=0.0)))
        return s


def is_calibration_session(metadata: dict[str, dict[str, str]]) -> bool:
    """Whether a session was recorded by ``adaproj calibrate`` or simulated by
    ``adaproj simulate-calibration`` (its metadata says so)."""
    session = metadata.get("session", {})
    return session.get("kind") == "calibration" or session.get("command") == "calibrate"


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
    if is_calibration_session(scan.metadata):
        raise InputError(
            f"{path} is a calibration session (patterns and captures, nothing projected): "
            f"solve it with `adaproj calibrate --replay {path}`"
        )
    faults = session_faults(scan.metadata)
    damage = scan.damage()
    if damage is not None:  # in the summary's session_file; `adaproj replay` says it
        log.debug("%s: %s", path.name, damage)
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
    if options.calibration is not None:
        cal = options.calibration.with_depth(cal.depth)
    settings = options.app_settings()
    display = MemoryDisplay(cal.projector.width, cal.projector.height, replay.clock)
    rt = Runtime(cal, display, replay.clock, [builtin_item()], settings, mask_content_map, frames)
    if options.cpu_times:
        rt.telemetry.times.clock = time.process_time
    link = LinkReplay(store, rt)
    scorer = None
    handheld = None
    side = SideViews(rt) if options.side_views and out_dir is not None else None
    spec_raw = scan.attachments.get(schemas.TRUTH_SURFACE_ATTACHMENT)
    if options.score and spec_raw is not None:
        scene = scene_of_session(json.loads(spec_raw), scan.attachments)
        scorer = Scorer(scene, rt, scan.attachments) if options.distortion else None
        handheld = HandheldScorer(
            scene,
            scoring_projector(scan.attachments, cal.projector),
            settings.display.stabiliser.margin,
            _hand(scan.metadata),
        )
        rt.screen.on_refresh = handheld.on_refresh
    period_ns = rt.screen.period_ns
    lead_ns = round(settings.display.lead_s * 1e9)
    vsync = 0
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
            vsync = t0 + period_ns
        while vsync - lead_ns < rec.receive_ns:  # refreshes computed before this record
            rt.screen.refresh(vsync)
            vsync += period_ns
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
            if handheld is not None:
                handheld.add_truth(rec)
        elif isinstance(rec, SerialTraffic):
            link.feed(rec)
        if rt.calibration_wanted:  # the hold gesture: no devices to hand over here
            rt.recalibrate(None, "a replay has no devices to calibrate")
        if rt.colour_wanted:  # the tap-then-hold gesture: no camera here either
            rt.remeasured(None, "a replay has no camera to measure the colour with")
        if n_records % 200 == 0:
            rss.append(round(rss_mb(), 1))
    if t0 is None:
        raise InputError(f"session {path} holds no records")
    rt.tick()
    rss.append(round(rss_mb(), 1))
    pictures = [] if side is None else side.pictures(t0)
    hand_section = {**refresh_summary(rt.telemetry), "margin": settings.display.stabiliser.margin}
    if handheld is not None:
        handheld.finish()
        hand_section.update(handheld.summary())
        frames.handheld_plot = _plot(handheld, t0)
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
        handheld=hand_section,
    )
    if result["link"]["rx_bytes"]:
        log.info("link: %s", {k: v for k, v in result["link"].items() if k != "mismatched"})
    frames.side_views = pictures
    return result, frames


def _hand(metadata: dict[str, dict[str, str]]) -> dict[str, Any] | None:
    """The simulated hand's intent recorded in the session, if any."""
    raw = metadata.get("session", {}).get(HAND_KEY)
    if raw is None:
        return None
    try:
        hand = json.loads(raw)
    except ValueError as e:
        raise InputError(f"session metadata {HAND_KEY} is malformed: {e}") from None
    return hand if isinstance(hand, dict) else None


def _plot(handheld: HandheldScorer, t0: int) -> Any:
    """The content's centre on the surface, stabilised and not (None: nothing scored)."""
    t, on, off = handheld.trajectories()
    if len(t) < 2:
        return None
    centre = len(on[0]) - 3 - (len(on[0]) - 2) // 2  # the middle of the content grid
    return motion_plot((t - t0) / 1e9, on[:, centre], off[:, centre])


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
