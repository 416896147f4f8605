"""ClipFrames (frames and their content maps in clip time) and the ClipPlayer's stages: a
clip cut while it plays keeps its last good frame and map up, a loop starts the map
again, the stages are timed on the injected clock."""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.content.clip import ClipFrames
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.content.temporal import TemporalContentMap
from adaproj_edge.content.video import VideoFrame, check_video
from adaproj_edge.errors import VideoError
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.render.clipplayer import STAGES, ClipPlayer
from adaproj_edge.render.display_maps import DisplayMapBuilder
from adaproj_edge.render.frame import render_frame
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner
from adaproj_edge.warp.warpmap import Grid
from tests.content.clips import write_clip

SIZE = (160, 96)
FPS = 20.0


def clip_frames(path: Path) -> ClipFrames:
    info = check_video(path)
    return ClipFrames(path, TemporalContentMap(SIZE, SaliencyModel()), info)


def test_frames_and_maps_follow_clip_time_and_restart_at_a_loop(tmp_path: Path) -> None:
    clip = clip_frames(write_clip(tmp_path / "c.avi", n=6, size=SIZE, fps=FPS))
    first = clip.frame(0.0)
    m0 = clip.content_map(first)
    assert clip.content_map(clip.frame(0.01)) is m0  # the same frame: the same map
    for i in range(1, 6):
        f = clip.frame(i / FPS)
        assert (f.index, f.loop) == (i, 0)
        clip.content_map(f)
    assert clip.maps.frames == 6
    wrapped = clip.frame(6 / FPS)
    assert (wrapped.index, wrapped.loop) == (0, 1)
    again = clip.content_map(wrapped)
    assert clip.maps.frames == 1  # started again as on a first frame
    assert np.allclose(again.values, m0.values)
    assert clip.period == pytest.approx(1 / FPS) and clip.size == SIZE
    clip.close()


def test_maps_of_another_size_are_refused(tmp_path: Path) -> None:
    path = write_clip(tmp_path / "c.avi", n=3, size=SIZE)
    with pytest.raises(ValueError, match="content maps sized"):
        ClipFrames(path, TemporalContentMap((320, 192), SaliencyModel()))


def test_a_clip_cut_while_playing_keeps_its_last_good_frame_and_map(tmp_path: Path) -> None:
    src = write_clip(tmp_path / "c.avi", n=20, size=SIZE, fps=FPS)
    path = tmp_path / "play.avi"
    shutil.copy(src, path)
    surface = simulate_surface("sphere-concave")
    grid = Grid(cols=8, rows=6)
    planner = WarpPlanner(surface.projector, grid, PlanSettings(warm_start=True), WarpCache())
    display = DisplayMapBuilder(surface.projector, grid.vertices(surface.projector))
    settings = WarpSettings(mode="content", grid=grid, max_iterations=4)
    ticks = itertools.count()
    clock = lambda: 0.001 * next(ticks)  # noqa: E731 - 1 ms a reading
    player = ClipPlayer(clip_frames(path), surface, planner, display, settings, clock)
    good = [player.play(i / FPS, 1 / FPS) for i in range(3)]
    shown_good = good[-1].image.copy()
    last_map = good[-1].content_map
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])  # the file is cut while it plays
    later, images = [], []
    for i in range(3, 20):
        later.append(player.play(i / FPS, 1 / FPS))
        images.append(later[-1].image.copy())  # the player draws into one buffer
    assert all(p.frame.ok for p in good)
    assert all(set(p.stage_ms) == set(STAGES) for p in good + later)
    assert all(ms == pytest.approx(1.0) for p in good for ms in p.stage_ms.values())
    bad = [p for p in later if not p.frame.ok]
    assert bad and "does not decode" in (bad[0].frame.error or "")
    k = later.index(bad[0])
    last_good = (later[k - 1] if k else good[-1]).frame.image
    assert last_good is not None
    for p in bad:
        image = images[later.index(p)]
        assert p.content_map is (later[k - 1].content_map if k else last_map)
        # what is projected is the last good frame through this frame's warp
        expected = render_frame(last_good, display.maps(p.warp, player.weights))
        assert np.array_equal(image, expected)
    assert shown_good.max() > 0


def test_nothing_decoded_yet_is_an_error(tmp_path: Path) -> None:
    path = write_clip(tmp_path / "c.avi", n=5, size=SIZE)
    clip = clip_frames(path)
    bad = VideoFrame(0, 0, 0.0, None, "frame 1 of 5 does not decode")  # as the reader says
    with pytest.raises(VideoError, match=r"c\.avi"):
        clip.content_map(bad)
