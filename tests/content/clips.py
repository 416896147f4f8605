"""Test clips written with OpenCV's own writer (MPEG-4 Part 2, MJPEG, FFV1).

The OpenCV wheels' FFmpeg decodes H.264 but has no H.264 encoder (``avc1`` writers do
not open), so the one H.264 clip is committed: ``tests/fixtures/video/h264.mp4``
(320x180, 30 frames at 30 fps, a disc moving right over blurred noise; made with
Debian's ``ffmpeg -c:v libx264 -profile:v baseline``).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

H264 = Path(__file__).resolve().parents[1] / "fixtures" / "video" / "h264.mp4"


def frame(i: int, size: tuple[int, int] = (160, 96), speed: float = 4.0) -> NDArray[np.uint8]:
    """Frame ``i`` of a test clip: a disc moving right over fixed blurred noise."""
    w, h = size
    rng = np.random.default_rng(11)
    img = cv2.GaussianBlur(rng.integers(0, 255, (h, w, 3), dtype=np.uint8), (0, 0), 2)
    cx = int(w * 0.15 + speed * i) % w
    cv2.circle(img, (cx, h // 2), max(3, h // 6), (0, 200, 255), -1, cv2.LINE_AA)
    return np.asarray(img, np.uint8)


def write_clip(
    path: Path,
    fourcc: str = "MJPG",
    n: int = 20,
    size: tuple[int, int] = (160, 96),
    fps: float = 20.0,
    speed: float = 4.0,
) -> Path:
    """Write ``n`` frames of :func:`frame` with OpenCV's FFmpeg writer; returns ``path``."""
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), fps, size)
    assert writer.isOpened(), f"OpenCV cannot write {fourcc} to {path.suffix}"
    for i in range(n):
        writer.write(frame(i, size, speed))
    writer.release()
    return path
