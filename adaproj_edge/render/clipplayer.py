"""A clip played content-aware through the warp pipeline, one stage at a time.

:class:`ClipPlayer` is what ``adaproj video`` and ``tools/bench_video.py`` play a clip
with, the way the device does (docs/video.md): the content-free warp of the surface
once (the device takes it from its pose cache), then for every frame five stages, each
timed on its own:

``decode``  the frame of the clip time (:class:`~adaproj_edge.content.clip.ClipFrames`:
            loops; a frame that does not decode keeps the last good one);
``content`` its content map (:class:`~adaproj_edge.content.temporal.TemporalContentMap`:
            saliency every few frames, faces tracked, smoothed in time);
``refine``  the content-aware refinement, warm-started and filtered in time
            (:meth:`~adaproj_edge.warp.planner.WarpPlanner.refine` with ``frame_dt``);
``maps``    the renderer's maps of the warp (through the pose's pixel weights);
``render``  the projector frame (``cv2.remap``).

The stopwatch is injected (``clock``: seconds, monotonic), so the module holds no clock.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.content.clip import ClipFrames
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.content.video import VideoFrame
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.display_maps import DisplayMapBuilder
from adaproj_edge.render.frame import render_frame
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import ContentFreeWarp, WarpPlanner
from adaproj_edge.warp.warpmap import Warp

STAGES = ("decode", "content", "refine", "maps", "render")
"""The per-frame stages, in order."""


@dataclass
class PlayedFrame:
    """One frame played.

    Attributes
    ----------
    frame : VideoFrame
        What the reader gave (``error`` set when it did not decode: the last good image
        is shown).
    content_map : ContentMap
    warp : Warp
        The warp shown; ``image_xy`` (R, C, 2), NaN where no surface.
    image : (H, W, 3) uint8 array
        The projector frame (a buffer the player reuses: copy it to keep it).
    stage_ms : dict of str to float
        Milliseconds per stage (:data:`STAGES`).
    """

    frame: VideoFrame
    content_map: ContentMap
    warp: Warp
    image: NDArray[np.uint8]
    stage_ms: dict[str, float] = field(default_factory=dict)


class ClipPlayer:
    """Plays one clip onto one surface.

    Parameters
    ----------
    clip : ClipFrames
        The clip's frames and content maps.
    surface : Surface
    planner : WarpPlanner
        For the surface's projector (the device's: coarse-to-fine, warm starts).
    display : DisplayMapBuilder
        For the planner's grid.
    settings : WarpSettings
        Content-aware settings (``max_iterations`` bounds a pose's first solve).
    clock : callable
        Seconds, monotonic (``time.perf_counter``; a fake in tests).
    content_free : ContentFreeWarp, optional
        The surface's content-free warp for the clip's size (solved when not given).
    """

    def __init__(
        self,
        clip: ClipFrames,
        surface: Surface,
        planner: WarpPlanner,
        display: DisplayMapBuilder,
        settings: WarpSettings,
        clock: Callable[[], float],
        content_free: ContentFreeWarp | None = None,
    ) -> None:
        self.clip = clip
        self.surface = surface
        self.planner = planner
        self.display = display
        self.settings = settings
        self.clock = clock
        t0 = clock()
        self.content_free = content_free or planner.content_free(surface, clip.size, settings)
        self.content_free_ms = 1000.0 * (clock() - t0)
        self.weights = display.pixel_weights(self.content_free.warp)
        self._out: NDArray[np.uint8] | None = None

    def play(self, t: float, dt: float) -> PlayedFrame:
        """The frame of clip time ``t`` (s, looping), ``dt`` seconds after the last one.

        Raises
        ------
        VideoError
            No frame of the clip has decoded yet.
        """
        ms: dict[str, float] = {}
        mark = self.clock()

        def lap(stage: str) -> None:
            nonlocal mark
            now = self.clock()
            ms[stage] = 1000.0 * (now - mark)
            mark = now

        frame = self.clip.frame(t)
        lap("decode")
        cmap = self.clip.content_map(frame)
        lap("content")
        warp = self.planner.refine(
            self.surface, cmap, self.settings, self.content_free, frame_dt=dt
        )
        lap("refine")
        maps = self.display.maps(warp, self.weights)
        lap("maps")
        assert frame.image is not None  # the last good one; content_map raised if none
        self._out = render_frame(frame.image, maps, self._out)
        lap("render")
        return PlayedFrame(frame, cmap, warp, self._out, ms)
