"""The built-in content: a poster drawn in code, with its user mask.

A test card that shows what a warp does: a fine grid and circles (angle and size
distortion are plain to see), a sky and a meadow (texture the saliency model leaves
alone), and two figures (the subjects, also marked in the built-in mask).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

SIZE = (960, 600)

_FIGURES = ((0.27, 0.74, 1.4), (0.7, 0.76, 1.15))  # feet (x, y) as fractions, and scale


def _figure(
    img: NDArray[np.uint8], cx: float, cy: float, s: float, color: tuple[int, int, int]
) -> None:
    """A standing figure with its feet at (cx, cy) (fractions of the image)."""
    w, h = img.shape[1], img.shape[0]
    x, y, u = int(cx * w), int(cy * h), h * 0.09 * s
    paint = color
    cv2.circle(img, (x, int(y - 2.2 * u)), int(0.55 * u), paint, -1, cv2.LINE_AA)
    cv2.ellipse(
        img, (x, int(y - 0.6 * u)), (int(0.7 * u), int(1.2 * u)), 0, 0, 360, paint, -1, cv2.LINE_AA
    )
    for dx in (-0.3, 0.3):
        cv2.line(
            img,
            (x, int(y)),
            (int(x + dx * u * 2), int(y + 1.6 * u)),
            paint,
            max(2, int(0.3 * u)),
            cv2.LINE_AA,
        )


def poster(size: tuple[int, int] = SIZE) -> NDArray[np.uint8]:
    """The built-in content image, BGR uint8 of ``size`` (w, h)."""
    w, h = size
    y = np.linspace(0.0, 1.0, h)[:, None, None]
    sky = (
        np.array([235, 200, 150], dtype=np.float64) * (1 - 0.4 * y)
        + np.array([255, 240, 225]) * 0.4 * y
    )
    grass = np.array([70, 150, 90], dtype=np.float64)
    horizon = 0.62
    base = np.where(y < horizon, sky, grass) * np.ones((1, w, 1))
    rng = np.random.default_rng(7)
    texture = rng.normal(0.0, 9.0, (h, w, 1)) * (y >= horizon)
    img: NDArray[np.uint8] = np.clip(base + texture, 0, 255).astype(np.uint8)
    step = max(8, w // 24)
    for gx in range(0, w, step):
        cv2.line(img, (gx, 0), (gx, h - 1), (255, 255, 255), 1, cv2.LINE_AA)
    for gy in range(0, h, step):
        cv2.line(img, (0, gy), (w - 1, gy), (255, 255, 255), 1, cv2.LINE_AA)
    r = int(0.16 * h)
    for cx in (0.12, 0.5, 0.88):
        cv2.circle(img, (int(cx * w), int(0.25 * h)), r, (60, 60, 60), 3, cv2.LINE_AA)
    cv2.circle(img, (int(0.5 * w), int(0.25 * h)), int(0.08 * h), (40, 200, 255), -1, cv2.LINE_AA)
    for (cx, cy, s), color in zip(_FIGURES, ((40, 40, 200), (150, 60, 30)), strict=True):
        _figure(img, cx, cy, s, color)
    cv2.putText(
        img,
        "adaproj",
        (int(0.36 * w), int(0.93 * h)),
        cv2.FONT_HERSHEY_DUPLEX,
        h / 300,
        (255, 255, 255),
        max(1, h // 200),
        cv2.LINE_AA,
    )
    return img


def poster_mask(size: tuple[int, int] = SIZE) -> NDArray[np.float32]:
    """The built-in user mask (h, w) in [0, 1]: the two figures, generously outlined."""
    w, h = size
    mask = np.zeros((h, w), dtype=np.uint8)
    for cx, cy, s in _FIGURES:
        cv2.ellipse(
            mask,
            (int(cx * w), int(cy * h - 0.07 * h * s)),
            (int(0.11 * h * s), int(0.27 * h * s)),
            0,
            0,
            360,
            255,
            -1,
        )
    return mask.astype(np.float32) / 255.0
