"""Playing a clip on the device: its frames at the clip's own rate on the runtime's clock.

When the active content item is a clip, the runtime (:mod:`adaproj_edge.app.runtime`)
holds a :class:`Playback` of it. At every tick it asks whether a frame is due
(:meth:`Playback.due`) and, if so, takes it (:meth:`Playback.advance`: decoded and its
content map made through a :class:`~adaproj_edge.content.temporal.TemporalContentMap`)
and shows it: refined per frame (the planner's ``frame_dt`` path, warm-started from the
pose's content-free warp) while the runtime projects content-aware, through the maps
shown otherwise (plain, content-free).

- **Time**: clip time is the injected clock's time since the clip was activated, less
  the time spent paused; the clip loops (the reader wraps round). No wall clock: a
  replay on a virtual clock shows the same frames every time.
- **Bounded per tick**: at most one frame is decoded, mapped and shown per tick. A
  runtime that falls behind shows the frame due now; the frames in between are skipped
  (grabbed by the decoder, not converted) and counted (``clip_skipped``). A frame
  handed to the display more than one clip period after its time counts as late
  (``clip_late``).
- **Decode failures**: a frame that does not decode is not shown (the last good frame
  stays up), counted (``clip_errors``) and logged with its reason at most once every
  ``error_log_s`` seconds of the runtime's clock.
- **Pause**: :meth:`Playback.toggle` freezes clip time (the frame shown stays up) and
  resumes it where it was.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.arrays import Image
from adaproj_edge.content.clip import ClipFrames
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.content.temporal import TemporalContentMap
from adaproj_edge.content.video import VideoFrame
from adaproj_edge.errors import VideoError

log = logging.getLogger(__name__)

ERROR_LOG_S = 5.0
"""Seconds (runtime clock) between two log lines about frames that do not decode."""


@dataclass(frozen=True)
class ClipStep:
    """A frame of the clip to show.

    Attributes
    ----------
    frame : VideoFrame
        The frame (decoded: ``error`` is None).
    content_map : ContentMap
        Its content map.
    dt : float
        Clip seconds since the frame shown before it (one period when none was).
    """

    frame: VideoFrame
    content_map: ContentMap
    dt: float

    @property
    def image(self) -> Image:
        """The frame's pixels, (h, w, 3) uint8 BGR."""
        assert self.frame.image is not None  # a step is only made of a decoded frame
        return self.frame.image


class Playback:
    """One clip item being played.

    Parameters
    ----------
    clip : ClipFrames
        The clip's frames and content maps.
    name : str
        The item's name (for logs and status).
    start_ns : int
        The runtime clock's time of clip time 0.
    telemetry : Telemetry
        Where the ``clip_*`` counters and events go.
    on_error : callable, optional
        Called with the reason of a frame that did not decode (when it is logged).
    error_log_s : float
        Seconds between two log lines about frames that do not decode.
    """

    def __init__(
        self,
        clip: ClipFrames,
        name: str,
        start_ns: int,
        telemetry: Telemetry,
        on_error: Callable[[str], None] | None = None,
        error_log_s: float = ERROR_LOG_S,
    ) -> None:
        self.clip = clip
        self.name = name
        self.telemetry = telemetry
        self.on_error = on_error
        self.error_log_ns = round(error_log_s * 1e9)
        self._origin_ns = start_ns
        self._paused_ns: int | None = None
        self._at: tuple[int, int] | None = None  # (loop, index) last taken, good or not
        self._due_t = 0.0  # clip time of the frame last taken
        self._logged_ns: int | None = None
        self.current: ClipStep | None = None  # the last good frame taken

    @classmethod
    def open(
        cls,
        path: Path,
        maps: TemporalContentMap,
        name: str,
        start_ns: int,
        telemetry: Telemetry,
        on_error: Callable[[str], None] | None = None,
    ) -> Playback:
        """A playback of the clip at ``path`` with content maps ``maps``.

        Raises
        ------
        VideoError
            The clip cannot be opened.
        """
        clip = ClipFrames(path, maps, log_failures=False)  # logged here, rate-limited
        return cls(clip, name, start_ns, telemetry, on_error)

    @property
    def period(self) -> float:
        """Seconds between two frames of the clip."""
        return self.clip.period

    @property
    def paused(self) -> bool:
        """Whether clip time stands still."""
        return self._paused_ns is not None

    def clip_time(self, now_ns: int) -> float:
        """Clip seconds played at ``now_ns`` (the runtime's clock; pauses left out)."""
        ref = self._paused_ns if self._paused_ns is not None else now_ns
        return max(0, ref - self._origin_ns) / 1e9

    def _serial(self, at: tuple[int, int]) -> int:
        return at[0] * self.clip.info.frame_count + at[1]

    def due(self, now_ns: int) -> bool:
        """Whether a frame other than the last one taken is due at ``now_ns``."""
        if self.paused:
            return False
        return self.clip.reader.position(self.clip_time(now_ns)) != self._at

    def advance(self, now_ns: int) -> ClipStep | None:
        """Decode the frame due at ``now_ns`` and make its content map.

        Returns the step to show, or None when the frame did not decode (the last good
        one stays up; counted, logged at most every ``error_log_s``).
        """
        t = self.clip_time(now_ns)
        at = self.clip.reader.position(t)
        if self._at is not None:
            missed = self._serial(at) - self._serial(self._at) - 1
            if missed > 0:
                self.telemetry.count("clip_skipped", missed)
        self._at = at
        self._due_t = self.clip.reader.time_of(at[1], at[0])
        try:
            frame = self.clip.frame(t)
            error = frame.error
            cmap = None if error is not None else self.clip.content_map(frame)
        except VideoError as e:  # the file went away at a loop, say
            frame, error, cmap = None, str(e), None
        if frame is None or error is not None or cmap is None:
            self._failed(now_ns, error or "no frame")
            return None
        last = self.current
        dt = self.period if last is None else max(frame.t - last.frame.t, self.period)
        self.current = ClipStep(frame, cmap, dt)
        return self.current

    def shown(self, now_ns: int) -> None:
        """The frame last taken was handed to the display at ``now_ns``."""
        self.telemetry.count("clip_frames")
        if self.clip_time(now_ns) - self._due_t > self.period + 1e-9:
            self.telemetry.count("clip_late")

    def toggle(self, now_ns: int) -> bool:
        """Pause, or resume where it was paused; returns whether it is paused now."""
        if self._paused_ns is None:
            self._paused_ns = now_ns
        else:
            self._origin_ns += now_ns - self._paused_ns
            self._paused_ns = None
        return self.paused

    def status(self, now_ns: int) -> dict[str, object]:
        """What the link's status shows of the playback."""
        cur = self.current
        return {
            "name": self.name,
            "paused": self.paused,
            "t": round(self.clip_time(now_ns), 3),
            "frame": None if cur is None else cur.frame.index,
            "fps": round(self.clip.info.fps, 3),
        }

    def close(self) -> None:
        """Release the decoder."""
        self.clip.close()

    def _failed(self, now_ns: int, reason: str) -> None:
        self.telemetry.count("clip_errors")
        logged = self._logged_ns
        if logged is not None and now_ns - logged < self.error_log_ns:
            return
        self._logged_ns = now_ns
        message = f"{self.name}: {reason}; keeping the last good frame"
        log.warning("%s", message)
        self.telemetry.event(now_ns, "clip_error", item=self.name, message=message)
        if self.on_error is not None:
            self.on_error(message)
