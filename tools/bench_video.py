#!/usr/bin/env python3
"""Content-aware video on one core: frames per second, stage times, late frames.

Makes a 1280x720 clip with OpenCV's own writer (MPEG-4 Part 2, ``mp4v`` in .mp4: the
OpenCV wheels decode H.264 but cannot encode it) from ``tests/content/clips.py``
(``--clip``: ``face``, the default, a face still for a second on a brick texture, then
moving right across 60 % of the width; ``subject``, an orange ellipse moving across
blurred noise), and plays it onto a surface (default: the concave sphere) at the
device's grid, one thread, with the device's content maps (saliency every 4th frame,
a face detection every 6th or so spread over five frames, one band of scales each, the
faces followed on every frame; the model and a band never on one frame after the
first), three ways, in the same run:

- **content-aware** (ours, as the device and ``adaproj video`` play it:
  :class:`~adaproj_edge.render.clipplayer.ClipPlayer`): decode, content map, warm
  refinement filtered in time, maps, render;
- **content-free** (the paper's way for video, §5.4): decode and render through the
  fixed content-free warp's maps (made once);
- **independent**: decode, content map, a full cold solve of every frame
  (``compute_warp``), maps, render (``--independent-frames`` frames: it is slow).

For each: sustained fps (frames / total time, stages one after the other on one core),
each stage's median, p95 and largest (ms), and late frames (% of frames whose stages together
took longer than the clip's frame period). Ratios are against the content-free way,
measured in the same run; the load average is printed (the machine is shared). ``--cpu`` times the
CPU time of the thread instead of the wall clock (one thread: what one idle core would
take, on a machine shared with other jobs).

    .venv/bin/python tools/bench_video.py [--frames 150] [--independent-frames 20]
        [--surface sphere-concave] [--size 1280x720] [--fps 30] [--clip face|subject]
        [--low-pass] [--line-fit] [--cpu]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.content.clips (the moving subject)

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from adaproj_edge.app.settings import AppSettings  # noqa: E402
from adaproj_edge.content.clip import ClipFrames  # noqa: E402
from adaproj_edge.content.faces import FaceDetector  # noqa: E402
from adaproj_edge.content.facetrack import FaceTracker  # noqa: E402
from adaproj_edge.content.model import SaliencyModel  # noqa: E402
from adaproj_edge.content.temporal import TemporalContentMap  # noqa: E402
from adaproj_edge.content.video import check_video  # noqa: E402
from adaproj_edge.geometry.analytic import simulate_surface  # noqa: E402
from adaproj_edge.geometry.surface import Surface  # noqa: E402
from adaproj_edge.render.clipplayer import STAGES, ClipPlayer  # noqa: E402
from adaproj_edge.render.display_maps import DisplayMapBuilder  # noqa: E402
from adaproj_edge.render.frame import render_frame  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from adaproj_edge.warp.engine import WarpSettings  # noqa: E402
from adaproj_edge.warp.mesh import WarpCache  # noqa: E402
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner, compute_warp  # noqa: E402
from adaproj_edge.warp.temporal import LINE_FIT, LOW_PASS, TemporalWarpSettings  # noqa: E402
from tests.content.clips import face_frame, subject_frame  # noqa: E402

Times = dict[str, list[float]]


def make_clip(path: Path, n: int, size: tuple[int, int], fps: float, kind: str = "face") -> Path:
    """``n`` frames of ``kind`` (``face``: still for a second, then moving; ``subject``:
    moving from the start), mp4v, at ``size`` and ``fps``."""
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter.fourcc(*"mp4v"), fps, size)
    if not writer.isOpened():
        raise SystemExit("OpenCV cannot write mp4v here")
    still = round(fps) if kind == "face" else 0
    speed = 0.6 * size[0] / max(1, n - still)  # across 60 % of the width
    for i in range(n):
        if kind == "face":
            image = face_frame(i, size, still=still - 1, speed=speed)[0]
        else:
            image = subject_frame(i, size, speed, start=0.2)[0]
        writer.write(image)
    writer.release()
    return path


_MODEL: list[SaliencyModel] = []


def shared_model() -> SaliencyModel:
    """The saliency model every way plays with: one session for the process, as the
    device keeps one (``app/content.py``), so its first runs' warm-up is paid once (by the
    tool's warm-up play), not by the first frames of every way measured."""
    if not _MODEL:
        _MODEL.append(SaliencyModel())
    return _MODEL[0]


class Rig:
    """The device's planner, display maps and content maps for one clip
    (``temporal``: the clip's warp settings, default the device's)."""

    def __init__(
        self, clip: Path, surface: Surface, temporal: TemporalWarpSettings | None = None
    ) -> None:
        s = AppSettings()
        self.info = check_video(clip)
        self.size = (self.info.width, self.info.height)
        self.settings = WarpSettings(
            mode="content", grid=s.grid, max_iterations=s.refine_iterations
        )
        plan = PlanSettings(refine_factor=s.refine_factor, warm_start=True)
        if temporal is not None:
            plan = replace(plan, temporal=temporal)
        self.planner = WarpPlanner(surface.projector, s.grid, plan, WarpCache())
        p = surface.projector
        self.display = DisplayMapBuilder(p, s.grid.vertices(p), s.map_scale)
        maps = TemporalContentMap(
            self.size,
            shared_model(),
            tracker=FaceTracker(FaceDetector()),
            grid=(s.grid.rows, s.grid.cols),
        )
        self.clip = ClipFrames(clip, maps, self.info)
        self.surface = surface


Clock = Callable[[], float]


def content_aware(
    clip: Path,
    surface: Surface,
    n: int,
    temporal: TemporalWarpSettings | None = None,
    clock: Clock = time.perf_counter,
) -> Times:
    rig = Rig(clip, surface, temporal)
    player = ClipPlayer(rig.clip, surface, rig.planner, rig.display, rig.settings, clock)
    fps = rig.info.fps
    times: Times = {k: [] for k in STAGES}
    for i in range(n):
        played = player.play(i / fps, 1 / fps)
        for k, v in played.stage_ms.items():
            times[k].append(v)
    rig.clip.close()
    return times


def content_free(clip: Path, surface: Surface, n: int, clock: Clock = time.perf_counter) -> Times:
    rig = Rig(clip, surface)
    cf = rig.planner.content_free(surface, rig.size, rig.settings)
    maps = rig.display.maps(cf.warp)
    fps = rig.info.fps
    times: Times = {"decode": [], "render": []}
    out = None
    for i in range(n):
        t0 = clock()
        f = rig.clip.frame(i / fps)
        t1 = clock()
        assert f.image is not None
        out = render_frame(f.image, maps, out)
        t2 = clock()
        times["decode"].append(1000 * (t1 - t0))
        times["render"].append(1000 * (t2 - t1))
    rig.clip.close()
    return times


def independent(clip: Path, surface: Surface, n: int, clock: Clock = time.perf_counter) -> Times:
    rig = Rig(clip, surface)
    fps = rig.info.fps
    times: Times = {k: [] for k in STAGES}
    out = None
    for i in range(n):
        lap = Lap(times, clock)
        f = rig.clip.frame(i / fps)
        lap("decode")
        cmap = rig.clip.content_map(f)
        lap("content")
        warp = compute_warp(surface, rig.size, cmap, rig.settings)
        lap("refine")
        maps = rig.display.maps(warp)
        lap("maps")
        assert f.image is not None
        out = render_frame(f.image, maps, out)
        lap("render")
    rig.clip.close()
    return times


class Lap:
    """Adds the time since the last lap to ``times[stage]`` (ms)."""

    def __init__(self, times: Times, clock: Clock = time.perf_counter) -> None:
        self.times, self.clock, self.mark = times, clock, clock()

    def __call__(self, stage: str) -> None:
        now = self.clock()
        self.times[stage].append(1000 * (now - self.mark))
        self.mark = now


def p95(xs: list[float]) -> float:
    return float(np.percentile(xs, 95))


def report(name: str, times: Times, period_ms: float, base_fps: float | None) -> float:
    totals = np.sum([times[k] for k in times], axis=0)
    fps = 1000.0 * len(totals) / float(np.sum(totals))
    late = 100.0 * float(np.mean(totals > period_ms))
    ratio = "" if base_fps is None else f"  {fps / base_fps:.2f}x the content-free fps"
    print(f"\n{name}: {len(totals)} frames, {fps:.1f} fps on one core, {late:.1f} % late{ratio}")
    stages = ", ".join(
        f"{k} {statistics.median(v):.1f}/{p95(v):.1f}/{max(v):.1f}" for k, v in times.items()
    )
    print(f"  stage median/p95/max ms: {stages}")
    print(f"  frame median/p95 ms: {statistics.median(totals):.1f}/{p95(list(totals)):.1f}")
    late_frames = [
        f"#{i} {totals[i]:.0f} ms ({max(times, key=lambda k: times[k][i])} "
        f"{max(v[i] for v in times.values()):.0f})"
        for i in np.flatnonzero(totals > period_ms)
    ]
    if late_frames:
        print(f"  late frames (slowest stage): {', '.join(late_frames)}")
    return fps


def main() -> None:
    apply_thread_policy(1)  # one thread: the figures are per core
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--independent-frames", type=int, default=20)
    ap.add_argument("--surface", default="sphere-concave")
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--clip", choices=("face", "subject"), default="face")
    ap.add_argument("--cpu", action="store_true", help="CPU time of the thread, not wall")
    ap.add_argument(
        "--low-pass",
        action="store_true",
        help="also content-aware with warp.temporal.LOW_PASS (the defaults before issue 15)",
    )
    ap.add_argument(
        "--line-fit",
        action="store_true",
        help="also content-aware with warp.temporal.LINE_FIT (the plain line fit)",
    )
    args = ap.parse_args()
    clock = time.thread_time if args.cpu else time.perf_counter
    w, h = (int(x) for x in args.size.split("x"))
    surface = simulate_surface(args.surface)
    with tempfile.TemporaryDirectory() as d:
        clip = make_clip(Path(d) / "clip.mp4", args.frames, (w, h), args.fps, args.clip)
        print(
            f"clip {args.clip} {w}x{h} mp4v (OpenCV's writer), {args.frames} frames at "
            f"{args.fps:g} fps; {'CPU time of the thread' if args.cpu else 'wall clock'}; "
            f"surface {args.surface}, grid {AppSettings().grid}, one thread; "
            f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
        )
        period = 1000.0 / args.fps
        content_aware(clip, surface, min(10, args.frames), clock=clock)  # load code and libraries
        free_times = content_free(clip, surface, args.frames, clock)
        free = report("content-free (the paper's way)", free_times, period, None)
        ours = content_aware(clip, surface, args.frames, clock=clock)
        ours_fps = report("content-aware (ours)", ours, period, free)
        if args.low_pass:
            low = content_aware(clip, surface, args.frames, LOW_PASS, clock)
            report("content-aware, LOW_PASS (coarse grid, low-pass)", low, period, free)
        if args.line_fit:
            fit = content_aware(clip, surface, args.frames, LINE_FIT, clock)
            report("content-aware, LINE_FIT (full grid, plain line fit)", fit, period, free)
        n = min(args.independent_frames, args.frames)
        indep_times = independent(clip, surface, n, clock)
        indep = report("independent full solves", indep_times, period, free)
        print(f"\nours / independent: {ours_fps / indep:.1f}x the fps")
        medians = {k: statistics.median(v) for k, v in ours.items()}
        slowest = max(medians, key=lambda k: medians[k])
        print(
            f"pipelined on separate cores, one stage per core: bounded by {slowest} "
            f"({medians[slowest]:.1f} ms median) -> {1000 / medians[slowest]:.0f} fps"
        )
        print(f"load average at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
