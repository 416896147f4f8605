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


SUBJECT_AXES = (0.11, 0.28)
"""Half-axes of the moving subject, as fractions of the frame's width and height."""


def subject_frame(
    i: int, size: tuple[int, int] = (640, 360), speed: float = 6.0, start: float = 0.2
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Frame ``i`` of a clip with a subject moving across a textured background, and
    the subject's true mask (h, w).

    The background is fixed blurred noise; the subject an orange ellipse (half-axes
    :data:`SUBJECT_AXES`) whose centre starts at ``start`` of the width, halfway down,
    and moves right ``speed`` px a frame (0: a still scene).
    """
    w, h = size
    rng = np.random.default_rng(3)
    img = cv2.GaussianBlur(rng.integers(60, 160, (h, w, 3), dtype=np.uint8), (0, 0), 3)
    cx, cy = start * w + speed * i, 0.5 * h
    ax, ay = SUBJECT_AXES[0] * w, SUBJECT_AXES[1] * h
    centre, axes = (round(cx * 16), round(cy * 16)), (round(ax * 16), round(ay * 16))
    cv2.ellipse(img, centre, axes, 0, 0, 360, (0, 200, 255), -1, cv2.LINE_AA, shift=4)
    yy, xx = np.mgrid[0:h, 0:w]
    mask = ((xx - cx) / ax) ** 2 + ((yy - cy) / ay) ** 2 <= 1.0
    return np.asarray(img, np.uint8), np.asarray(mask)


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


def face_frame(
    i: int,
    size: tuple[int, int] = (640, 360),
    still: int = 30,
    speed: float = 6.0,
    face: int = 0,
) -> tuple[NDArray[np.uint8], tuple[float, float, float, float]]:
    """Frame ``i`` of a clip that starts still: a face at the left on a textured
    background, where it is on frames 0 to ``still``, then moving right ``speed`` px a
    frame (frame ``i`` > ``still``: ``speed * (i - still)`` px right of frame 0's); and
    the face's box (x, y, w, h).

    The background is scikit-image's brick texture; the face the ``face``-th of the
    Labeled Faces in the Wild crops (``tests/content/facescenes.py``), enlarged to 0.3 of
    the frame's height and blended in a skin tint with feathered edges.
    """
    from skimage import data

    w, h = size
    bg = cv2.cvtColor(data.brick(), cv2.COLOR_GRAY2BGR)
    img = cv2.resize(bg[: bg.shape[1] * h // w], size, interpolation=cv2.INTER_AREA)
    s = max(24, round(0.3 * h))
    x = 0.12 * w + speed * max(0, i - still)
    y = 0.5 * h - s / 2
    crop = np.round(data.lfw_subset()[face] * 255.0).astype(np.uint8)
    patch = cv2.resize(crop, (s, s), interpolation=cv2.INTER_CUBIC).astype(np.float64)
    alpha = np.zeros((s, s), np.float64)
    cv2.ellipse(alpha, (s // 2, s // 2), (int(s * 0.48), int(s * 0.5)), 0, 0, 360, 1.0, -1)
    alpha = cv2.GaussianBlur(alpha, (0, 0), s / 20)[:, :, None]
    skin = np.array([0.62, 0.75, 0.95])  # BGR
    xi, yi = round(x), round(y)
    region = img[yi : yi + s, xi : xi + s].astype(np.float64)
    mixed = alpha * patch[:, :, None] * skin + (1 - alpha) * region
    img[yi : yi + s, xi : xi + s] = np.clip(mixed, 0, 255).astype(np.uint8)
    return np.asarray(img, np.uint8), (float(xi), float(yi), float(s), float(s))
