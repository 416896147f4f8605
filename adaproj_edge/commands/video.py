"""``adaproj video``: a clip rendered content-aware onto a surface, as the device plays it.

Writes into ``--out``: ``projected.avi`` (the projector frames, Motion JPEG: the OpenCV
wheels cannot encode H.264), ``side.png`` (a few frames seen from beside the projector)
and ``frames.json`` (one object per frame: ``t``, ``image_xy``, ``iterations``,
``stage_ms`` and the distortion of the shown and of the content-free warp; docs/video.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from adaproj_edge.commands._inputs import grid_arg, load_surface
from adaproj_edge.commands._outputs import check_output_dir
from adaproj_edge.errors import InputError

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from adaproj_edge.geometry.surface import Surface
    from adaproj_edge.warp.quality import Quality

VIDEO_NAME = "projected.avi"
SIDE_NAME = "side.png"

SideFrame = tuple[float, "NDArray[np.uint8]", "NDArray[np.uint8]"]
"""A frame of the side view: its time (s), the clip's frame, the projector frame."""
FRAMES_NAME = "frames.json"


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "video",
        help="render a clip content-aware onto a surface, as the device plays it",
        description=(
            "Play CLIP (MP4, AVI: H.264, MPEG-4, MJPEG) content-aware onto the surface "
            "frame by frame, as the device does (warm-started refinement smoothed in time), "
            f"and write DIR/{VIDEO_NAME} (the projector frames, MJPEG), DIR/{SIDE_NAME} "
            f"(a few frames seen from the side) and DIR/{FRAMES_NAME} (per frame: the warp, "
            "the stage times and the distortion beside the content-free warp's)."
        ),
    )
    p.add_argument("clip", type=Path, help="the clip (.mp4, .avi, .mkv, .mov)")
    p.add_argument(
        "--surface", required=True, help="Surface file (.npz), mesh or a built-in surface name"
    )
    p.add_argument("--mask", type=Path, help="user mask: PNG, white = important, every frame")
    p.add_argument("--out", type=Path, required=True, help="folder to write into")
    p.add_argument("--grid", type=grid_arg, default=None, help="cells, e.g. 20x20")
    p.add_argument(
        "--frames", type=int, default=None, help="render only the first N frames (default: all)"
    )
    p.add_argument("--side-frames", type=int, default=4, help="frames in the side view (default 4)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.frames is not None and args.frames < 1:
        raise InputError(f"--frames must be at least 1, got {args.frames}")
    if args.side_frames < 1:
        raise InputError(f"--side-frames must be at least 1, got {args.side_frames}")
    out = check_output_dir(args.out, "output folder")

    import time

    from adaproj_edge.app.settings import AppSettings
    from adaproj_edge.content.clip import ClipFrames
    from adaproj_edge.content.faces import FaceDetector
    from adaproj_edge.content.facetrack import FaceTracker
    from adaproj_edge.content.mask import load_mask
    from adaproj_edge.content.model import SaliencyModel
    from adaproj_edge.content.temporal import TemporalContentMap
    from adaproj_edge.content.video import check_video
    from adaproj_edge.render.clipplayer import ClipPlayer
    from adaproj_edge.render.display_maps import DisplayMapBuilder
    from adaproj_edge.warp.engine import WarpSettings
    from adaproj_edge.warp.mesh import WarpCache
    from adaproj_edge.warp.planner import PlanSettings, WarpPlanner

    info = check_video(args.clip)
    size = (info.width, info.height)
    mask = None if args.mask is None else load_mask(args.mask, size)
    surface = load_surface(args.surface)
    s = AppSettings()
    grid = args.grid or s.grid
    settings = WarpSettings(mode="content", grid=grid, max_iterations=s.refine_iterations)
    plan = PlanSettings(refine_factor=s.refine_factor, warm_start=True)
    planner = WarpPlanner(surface.projector, grid, plan, WarpCache())
    display = DisplayMapBuilder(surface.projector, grid.vertices(surface.projector), s.map_scale)
    maps = TemporalContentMap(
        size,
        SaliencyModel(),
        mask=mask,
        tracker=FaceTracker(FaceDetector()),  # as the device: faces followed
        grid=(grid.rows, grid.cols),
    )
    clip = ClipFrames(args.clip, maps, info)
    try:
        player = ClipPlayer(clip, surface, planner, display, settings, time.perf_counter)
        n = info.frame_count if args.frames is None else min(args.frames, info.frame_count)
        records, side = _play(player, surface, n, out, args.side_frames)
    finally:
        clip.close()
    _write_json(out / FRAMES_NAME, records)
    _write_side(out / SIDE_NAME, surface, side)
    late = sum(sum(r["stage_ms"].values()) > 1000.0 / info.fps for r in records)
    print(
        f"wrote {out / VIDEO_NAME} ({n} frames at {info.fps:g} fps), {out / SIDE_NAME}, "
        f"{out / FRAMES_NAME}; {late} of {n} frames took longer than 1/{info.fps:g} s here"
    )
    return 0


def _play(
    player: Any, surface: Surface, n: int, out: Path, side_frames: int
) -> tuple[list[dict[str, Any]], list[SideFrame]]:
    """Play ``n`` frames into the video; their records and the side view's frames."""
    import cv2

    from adaproj_edge.fileio import atomic_write
    from adaproj_edge.warp.quality import measure

    fps = player.clip.info.fps
    p = surface.projector
    free_map = player.display.float_map(player.content_free.warp)
    picks = {round(i * (n - 1) / max(1, side_frames - 1)) for i in range(side_frames)}
    records: list[dict[str, Any]] = []
    side: list[SideFrame] = []
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".{VIDEO_NAME}.part.avi"
    fourcc = cv2.VideoWriter.fourcc(*"MJPG")
    writer = cv2.VideoWriter(str(tmp), cv2.CAP_FFMPEG, fourcc, fps, (p.width, p.height))
    if not writer.isOpened():
        raise InputError(f"cannot write {out / VIDEO_NAME}: OpenCV cannot open an MJPG writer")
    done = False
    try:
        for i in range(n):
            played = player.play(i / fps, 1.0 / fps)
            writer.write(played.image)
            if i in picks and played.frame.image is not None:
                side.append((i / fps, played.frame.image.copy(), played.image.copy()))
            cmap = played.content_map
            salient = cmap.full_size() >= cmap.threshold
            shown = measure(player.display.float_map(played.warp), surface, salient)
            free = measure(free_map, surface, salient)
            records.append(
                {
                    "t": round(i / fps, 6),
                    "image_xy": _vertices(played.warp.image_xy),
                    "iterations": int(played.warp.meta.get("iterations", 0)),
                    "stage_ms": {k: round(v, 3) for k, v in played.stage_ms.items()},
                    "distortion": _quality(*shown),
                    "content_free_distortion": _quality(*free),
                    **({"error": played.frame.error} if played.frame.error else {}),
                }
            )
            if (i + 1) % 10 == 0 or i + 1 == n:
                print(f"\rframe {i + 1}/{n}", end="", file=sys.stderr, flush=True)
        print(file=sys.stderr)
        writer.release()
        atomic_write(out / VIDEO_NAME, lambda f: f.write(tmp.read_bytes()))
        done = True
    finally:
        writer.release()
        tmp.unlink(missing_ok=True)
        if not done:
            print(file=sys.stderr)
    return records, side


def _vertices(xy: NDArray[np.floating]) -> list[list[list[float] | None]]:
    """Rows x cols of [x, y] (3 decimals), None where the warp has no vertex."""
    import numpy as np

    return [
        [None if not np.all(np.isfinite(v)) else [round(float(v[0]), 3), round(float(v[1]), 3)]
         for v in row]
        for row in xy
    ]  # fmt: skip


def _quality(overall: Quality, salient: Quality | None) -> dict[str, float | None]:
    """``{angle, size, salient_angle, salient_size}``; None where nothing was measured."""
    import math

    def num(x: float | None) -> float | None:
        return None if x is None or not math.isfinite(x) else round(x, 6)

    return {
        "angle": num(overall.angle_error),
        "size": num(overall.size_inconsistency),
        "salient_angle": num(None if salient is None else salient.angle_error),
        "salient_size": num(None if salient is None else salient.size_inconsistency),
    }


def _write_json(path: Path, records: list[dict[str, Any]]) -> None:
    import json

    from adaproj_edge.fileio import atomic_write_bytes

    atomic_write_bytes(path, json.dumps(records, separators=(",", ":")).encode())


def _write_side(path: Path, surface: Surface, frames: list[SideFrame]) -> None:
    """The picked frames seen from :data:`~adaproj_edge.render.viewer.DEFAULT_VIEWER`:
    a plain projector's above, the frames adaproj projected below, titled."""
    from adaproj_edge.fileio import write_image
    from adaproj_edge.render.project import show
    from adaproj_edge.render.sheet import row, stack, titled
    from adaproj_edge.render.viewer import DEFAULT_VIEWER, view, viewer_for
    from adaproj_edge.warp.engine import WarpSettings
    from adaproj_edge.warp.planner import compute_warp

    viewer = viewer_for(surface, DEFAULT_VIEWER)
    h, w = frames[0][1].shape[:2]
    plain_warp = compute_warp(surface, (w, h), None, WarpSettings(mode="standard"))
    plain = [view(surface, show(surface, c, plain_warp).frame, viewer) for _, c, _ in frames]
    shown = [view(surface, f, viewer) for _, _, f in frames]
    times = [f"{t:.2f} s" for t, _, _ in frames]
    x, y, z = DEFAULT_VIEWER
    title = (
        f"The clip on the surface, as a viewer at x {x:+.2f}, y {y:+.2f}, z {z:+.2f} m from "
        "the projector sees it: a plain projector above, adaproj (content-aware) below. "
        "Grey: surface left dark."
    )
    rows = [
        row(plain, [f"{t} plain projector" for t in times], 240),
        row(shown, [f"{t} adaproj" for t in times], 240),
    ]
    write_image(path, titled(stack(rows), [title]))
