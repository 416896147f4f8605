"""A clip being played: its frames in clip time and their content maps, in order.

:class:`ClipFrames` puts a :class:`~adaproj_edge.content.video.VideoReader` and a
:class:`~adaproj_edge.content.temporal.TemporalContentMap` together, as the device, the
off-line renderer (``adaproj video``) and the benchmark play a clip: ask for the frame
of a clip time (:meth:`ClipFrames.frame`: decodes forward, loops), then for its content
map (:meth:`ClipFrames.content_map`), so a caller can time the two stages apart.

- A frame that does not decode is a value: :meth:`ClipFrames.frame` returns it with
  ``error`` set and the last good image, and :meth:`ClipFrames.content_map` keeps the
  last map (nothing new to look at). The reader logs the reason once per loop.
- When the clip wraps round (a new loop) the content map starts again as on a first
  frame (the clip's first frame has nothing to do with its last).

No clock: the caller passes clip time.
"""

from __future__ import annotations

import os
from pathlib import Path

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.content.temporal import TemporalContentMap
from adaproj_edge.content.video import VideoFrame, VideoInfo, VideoReader
from adaproj_edge.errors import VideoError


class ClipFrames:
    """The frames of one checked clip and their content maps.

    Parameters
    ----------
    path : path-like
        The clip (passed :func:`~adaproj_edge.content.video.check_video`).
    maps : TemporalContentMap
        The clip's content maps (sized for the clip's frames, the item's mask in it).
    info : VideoInfo, optional
        The clip's probe (probed again when not given).
    log_failures : bool
        Whether the reader logs frames that do not decode (once per loop).

    Raises
    ------
    VideoError
        The clip cannot be opened.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        maps: TemporalContentMap,
        info: VideoInfo | None = None,
        log_failures: bool = True,
    ) -> None:
        self.reader = VideoReader(path, info, log_failures)
        self.maps = maps
        if maps.content_size != self.size:
            raise ValueError(f"content maps sized {maps.content_size} for a {self.size} clip")
        self._mapped: VideoFrame | None = None
        self._map: ContentMap | None = None

    @property
    def path(self) -> Path:
        """The clip's file."""
        return self.reader.path

    @property
    def info(self) -> VideoInfo:
        """The clip's size, rate, length and codec."""
        return self.reader.info

    @property
    def size(self) -> tuple[int, int]:
        """The frames' (w, h) in pixels."""
        return self.info.width, self.info.height

    @property
    def period(self) -> float:
        """Seconds between two frames of the clip."""
        return 1.0 / self.info.fps

    def frame(self, t: float) -> VideoFrame:
        """The frame to show at clip time ``t`` (s, looping): see
        :meth:`~adaproj_edge.content.video.VideoReader.at`."""
        return self.reader.at(t)

    def content_map(self, frame: VideoFrame) -> ContentMap:
        """The content map of ``frame`` (the one :meth:`frame` gave last).

        Returns the last map for a frame asked twice or one that did not decode; starts
        the map's history again at a new loop.

        Raises
        ------
        VideoError
            No frame of the clip has decoded yet (nothing to map).
        """
        last, cmap = self._mapped, self._map
        if cmap is not None and (not frame.ok or _same(last, frame)):
            return cmap
        if frame.image is None:
            raise VideoError(f"{self.path.name}: {frame.error}")
        if last is not None and frame.loop != last.loop:
            self.maps.reset()
        cmap = self.maps.update(frame.image)
        self._mapped, self._map = frame, cmap
        return cmap

    def close(self) -> None:
        """Release the decoder."""
        self.reader.close()


def _same(a: VideoFrame | None, b: VideoFrame) -> bool:
    return a is not None and (a.loop, a.index) == (b.loop, b.index)
