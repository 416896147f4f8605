"""Video content: probe, check and read clips through OpenCV's FFmpeg backend.

Accepted: MP4 (``.mp4``), AVI (``.avi``) and Matroska (``.mkv``) files holding H.264,
MPEG-4 Part 2 or Motion JPEG video (the codecs a Raspberry-Pi-class board decodes at
720p30 on one core). A file must start like its container (checked before FFmpeg
sees it, so no other demuxer - a playlist, say - is ever probed). :func:`check_video`
refuses, with a reason, a file that does not open, has no frames, uses another codec,
is too large, too long or too fast (:class:`VideoLimits`), or whose first or last frame
does not decode (a truncated or corrupt file). Every decode is bounded by a number of
frames, never by a clock.

:class:`VideoReader` plays a checked clip: frames in order, looped, each with its
presentation time; :meth:`VideoReader.at` gives the frame to show at a clip time (it
decodes forward, skipping what a late player missed). A frame that fails to decode is a
value (:class:`VideoFrame` with ``error`` set and the last good image), never an
exception: the player keeps the last good frame and logs why.

This file is about 400 lines on purpose: the checks and the reader share the
container and codec facts and the bounded decode.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from adaproj_edge.arrays import Image
from adaproj_edge.errors import VideoError

log = logging.getLogger(__name__)

# FFmpeg's own log lines (a damaged file gives several per frame) would come before our
# one line about the file; quiet unless the environment says otherwise. OpenCV reads
# this when it opens its first capture.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

VIDEO_EXTENSIONS = (".mp4", ".avi", ".mkv")

CODECS = {
    "avc1": "H.264",
    "h264": "H.264",
    "x264": "H.264",
    "mp4v": "MPEG-4",
    "fmp4": "MPEG-4",
    "xvid": "MPEG-4",
    "divx": "MPEG-4",
    "dx50": "MPEG-4",
    "mjpg": "MJPEG",
}
"""FourCC (lower case) -> codec name, for the codecs accepted."""

HEAD = 16
"""Bytes of a file's start that tell its container."""


@dataclass(frozen=True)
class VideoLimits:
    """What a clip may be.

    Attributes
    ----------
    max_side : int
        Width and height at most (px).
    max_pixels : int
        Width times height at most (1920 x 1080).
    max_fps : float
        Frame rate at most (the projector plays up to 30 fps; faster clips drop frames).
    max_frames : int
        Frames at most.
    max_duration : float
        Seconds at most.
    """

    max_side: int = 1920
    max_pixels: int = 1920 * 1080
    max_fps: float = 60.0
    max_frames: int = 18_000
    max_duration: float = 300.0


@dataclass(frozen=True)
class VideoInfo:
    """What a clip is: size, rate, length and codec.

    Attributes
    ----------
    width, height : int
        Frame size (px).
    fps : float
        Frames per second.
    frame_count : int
        Frames in the clip (from the container).
    codec : str
        FourCC as the container names it (``avc1``, ``FMP4``, ``MJPG``...).
    """

    width: int
    height: int
    fps: float
    frame_count: int
    codec: str

    @property
    def duration(self) -> float:
        """Seconds the clip lasts at its rate."""
        return self.frame_count / self.fps

    @property
    def codec_name(self) -> str:
        """The codec's common name (``H.264``, ``MPEG-4``, ``MJPEG``), or the FourCC."""
        return CODECS.get(self.codec.lower(), self.codec)


def is_video_name(name: str) -> bool:
    """Whether a file name has a video extension (:data:`VIDEO_EXTENSIONS`)."""
    return name.lower().endswith(VIDEO_EXTENSIONS)


def container_of(head: bytes) -> str | None:
    """The container a file's first bytes announce (``mp4``, ``avi``, ``mkv``), or None."""
    if len(head) >= 8 and head[4:8] == b"ftyp":
        return "mp4"
    if len(head) >= 12 and head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return "avi"
    if head[:4] == b"\x1a\x45\xdf\xa3":
        return "mkv"
    return None


def check_video_head(head: bytes, name: str) -> None:
    """Refuse a start of file that is not the container its name says.

    Raises
    ------
    VideoError
        ``head`` does not begin like an MP4, AVI or Matroska file matching ``name``.
    """
    want = Path(name).suffix.lower().lstrip(".")
    got = container_of(head)
    if got is None:
        raise VideoError(f"{name} is not an MP4, AVI or Matroska video")
    if got != want:
        raise VideoError(f"{name} is named .{want} but holds an {got.upper()} file")


def _open(path: Path) -> Any:
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    if not cap.isOpened():
        cap.release()
        return None
    return cap


def _fourcc(cap: Any) -> str:
    code = int(cap.get(cv2.CAP_PROP_FOURCC)) & 0xFFFFFFFF
    text = code.to_bytes(4, "little").decode("latin-1")
    return text if text.isprintable() and text.strip() else f"0x{code:08x}"


def probe(path: str | os.PathLike[str], what: str | None = None) -> VideoInfo:
    """Open a clip and read its size, rate, frame count and codec (nothing decoded).

    Raises
    ------
    VideoError
        The file does not start like a video container or FFmpeg cannot open it.
    """
    path = Path(path)
    what = what or path.name
    try:
        with path.open("rb") as f:
            head = f.read(HEAD)
    except OSError as e:
        raise VideoError(f"cannot read {what}: {e.strerror or e}") from None
    if container_of(head) is None:
        raise VideoError(f"{what} is not an MP4, AVI or Matroska video")
    cap = _open(path)
    if cap is None:
        raise VideoError(f"{what} cannot be opened as a video (truncated or corrupt file?)")
    try:
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        return VideoInfo(
            int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
            int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
            fps if math.isfinite(fps) else 0.0,
            int(count) if math.isfinite(count) and count > 0 else 0,
            _fourcc(cap),
        )
    finally:
        cap.release()


def check_limits(info: VideoInfo, what: str, limits: VideoLimits) -> None:
    """Refuse a probed clip whose codec, size, rate or length is not acceptable."""
    if info.codec.lower() not in CODECS:
        raise VideoError(
            f"{what} uses the {info.codec} codec; only H.264, MPEG-4 and MJPEG play on the device"
        )
    w, h = info.width, info.height
    if w < 2 or h < 2 or w > limits.max_side or h > limits.max_side or w * h > limits.max_pixels:
        raise VideoError(
            f"{what} is {w}x{h}; a clip may be at most {limits.max_side} px a side and "
            f"{limits.max_pixels} pixels"
        )
    if not 0.0 < info.fps <= limits.max_fps:
        raise VideoError(f"{what} runs at {info.fps:g} fps; 0 < fps <= {limits.max_fps:g}")
    if info.frame_count <= 0:
        raise VideoError(f"{what} has no frames")
    if info.frame_count > limits.max_frames:
        raise VideoError(f"{what} has {info.frame_count} frames, more than {limits.max_frames}")
    if info.duration > limits.max_duration:
        raise VideoError(
            f"{what} lasts {info.duration:.1f} s, longer than the {limits.max_duration:g} s allowed"
        )


def check_video(
    path: str | os.PathLike[str], what: str | None = None, limits: VideoLimits | None = None
) -> VideoInfo:
    """Probe a clip, check it against ``limits`` and decode its first and last frames.

    At most two frames are decoded (plus what FFmpeg decodes to reach the last one from
    its key frame), so the check ends in a time bounded by frames, whatever the bytes.

    Raises
    ------
    VideoError
        With the reason: not a video, cannot be opened, unsupported codec, too large,
        too fast, too long, no frames, or a frame that does not decode (truncated or
        corrupt).
    """
    path = Path(path)
    what = what or path.name
    limits = limits or VideoLimits()
    info = probe(path, what)
    check_limits(info, what, limits)
    cap = _open(path)
    if cap is None:
        raise VideoError(f"{what} cannot be opened as a video")
    try:
        for index in sorted({0, info.frame_count - 1}):
            if index and not cap.set(cv2.CAP_PROP_POS_FRAMES, float(index)):
                raise VideoError(f"{what}: cannot seek to frame {index + 1} (corrupt index?)")
            ok, frame = cap.read()
            if not ok or frame is None:
                raise VideoError(
                    f"{what}: frame {index + 1} of {info.frame_count} does not decode "
                    "(truncated or corrupt file)"
                )
            if frame.shape[:2] != (info.height, info.width):
                raise VideoError(
                    f"{what}: frame {index + 1} is {frame.shape[1]}x{frame.shape[0]}, "
                    f"the header says {info.width}x{info.height}"
                )
    finally:
        cap.release()
    return info


@dataclass(frozen=True)
class VideoFrame:
    """One frame to show.

    Attributes
    ----------
    index : int
        Frame number in the clip (0-based; restarts at each loop).
    loop : int
        How many times the clip has wrapped round before this frame.
    t : float
        Presentation time in seconds since the first frame of the first loop.
    image : (h, w, 3) uint8 or None
        The frame; on a decode failure the last good frame (None if there was none).
    error : str or None
        Why this frame could not be decoded; None when it was.
    """

    index: int
    loop: int
    t: float
    image: Image | None
    error: str | None = None

    @property
    def ok(self) -> bool:
        """Whether this frame decoded."""
        return self.error is None


class VideoReader:
    """A checked clip played in order and looped; decode failures are values.

    Parameters
    ----------
    path : path-like
        The clip (passed :func:`check_video`).
    info : VideoInfo, optional
        Its probe; probed again when not given.
    log_failures : bool
        Log a frame that does not decode (once per loop); False leaves it to the caller
        (the device's playback rate-limits its own).

    Raises
    ------
    VideoError
        The clip cannot be opened.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        info: VideoInfo | None = None,
        log_failures: bool = True,
    ) -> None:
        self.path = Path(path)
        self.info = info or probe(self.path)
        self.log_failures = log_failures
        if self.info.frame_count <= 0 or self.info.fps <= 0:
            raise VideoError(f"{self.path.name} has no frames to play")
        self._cap: Any = None
        self._next = 0  # the index the capture decodes next
        self._loop = 0
        self._failed = False
        self._last: Image | None = None
        self._shown: VideoFrame | None = None
        self._rewind()

    def _rewind(self) -> None:
        if self._cap is not None:
            self._cap.release()
        self._cap = _open(self.path)
        if self._cap is None:
            raise VideoError(f"{self.path.name} cannot be opened as a video")
        self._next = 0
        self._failed = False

    def _failure(self, index: int) -> VideoFrame:
        reason = f"frame {index + 1} of {self.info.frame_count} does not decode"
        # once per loop: a broken file fails at every frame after
        if not self._failed and self.log_failures:
            log.warning("%s: %s; keeping the last good frame", self.path.name, reason)
        self._failed = True
        return VideoFrame(index, self._loop, self.time_of(index, self._loop), self._last, reason)

    def close(self) -> None:
        """Release the decoder."""
        if self._cap is not None:
            self._cap.release()
            self._cap = None

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def last_good(self) -> Image | None:
        """The last frame that decoded, (h, w, 3) uint8, or None."""
        return self._last

    def time_of(self, index: int, loop: int) -> float:
        """Presentation time (s) of frame ``index`` of loop ``loop``."""
        return (loop * self.info.frame_count + index) / self.info.fps

    def position(self, t: float) -> tuple[int, int]:
        """(loop, index) of the frame shown at clip time ``t`` (s; negative is 0)."""
        n = max(0, math.floor(max(t, 0.0) * self.info.fps + 1e-9))
        return divmod(n, self.info.frame_count)

    def next(self) -> VideoFrame:
        """The next frame in order; after the last, the first again (next loop)."""
        if self._next >= self.info.frame_count:
            self._loop += 1
            self._rewind()
        index = self._next
        self._next += 1
        ok, frame = self._cap.read()
        if not ok or frame is None:
            self._shown = self._failure(index)
        else:
            self._last = np.asarray(frame, np.uint8)
            self._shown = VideoFrame(index, self._loop, self.time_of(index, self._loop), self._last)
        return self._shown

    def at(self, t: float) -> VideoFrame:
        """The frame to show at clip time ``t`` (s): decodes forward to it, looping.

        Asked again for the frame already shown, returns it without decoding. Frames
        between the last one shown and this one are skipped (grabbed, not converted);
        going back in time, or into another loop, restarts the decoder.
        """
        loop, index = self.position(t)
        shown = self._shown
        if shown is not None and (shown.loop, shown.index) == (loop, index):
            return shown
        if loop != self._loop or index < self._next:
            self._loop = loop
            self._rewind()
        while self._next < index:
            skipped = self._next
            self._next += 1
            if not self._cap.grab():
                self._next = index + 1
                self._shown = self._failure(index)
                log.debug("skipping to frame %d failed at frame %d", index + 1, skipped + 1)
                return self._shown
        return self.next()

    def __iter__(self) -> VideoReader:
        return self

    def __next__(self) -> VideoFrame:
        return self.next()
