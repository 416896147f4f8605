"""Pop-out displays with a known answer: a grid of items, one of them odd.

Each function returns the BGR image (800 x 1280, the projector's aspect), the centre of
the odd item and the centres of the others, in content pixels.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

Point = tuple[int, int]
Display = tuple[NDArray[np.uint8], Point, list[Point]]

H, W = 800, 1280
ROWS, COLS = 4, 6


def centres() -> list[Point]:
    """Item centres of the 4 x 6 grid."""
    return [(110 + 212 * j, 110 + 193 * i) for i in range(ROWS) for j in range(COLS)]


def _split(odd: int) -> tuple[Point, list[Point]]:
    c = centres()
    return c[odd], c[:odd] + c[odd + 1 :]


def colour_popout(odd: int) -> Display:
    """Green discs on gray, one red disc."""
    img = np.full((H, W, 3), 110, np.uint8)
    for k, (x, y) in enumerate(centres()):
        cv2.circle(img, (x, y), 42, (0, 0, 215) if k == odd else (0, 190, 0), -1)
    return (img, *_split(odd))


def orientation_popout(odd: int) -> Display:
    """Upright light bars on dark gray, one bar tilted by 45 degrees."""
    img = np.full((H, W, 3), 40, np.uint8)
    for k, (x, y) in enumerate(centres()):
        box = cv2.boxPoints(((x, y), (22, 120), 45.0 if k == odd else 0.0))
        cv2.fillPoly(img, [np.round(box).astype(np.int32)], (225, 225, 225))
    return (img, *_split(odd))


def intensity_popout(odd: int, seed: int = 0) -> Display:
    """A random gray texture, one bright disc on it (the others are texture too)."""
    rng = np.random.default_rng(seed)
    tex = rng.integers(50, 150, (H // 8, W // 8)).astype(np.uint8)
    gray = cv2.resize(tex, (W, H), interpolation=cv2.INTER_NEAREST)
    (x, y), others = _split(odd)
    cv2.circle(gray, (x, y), 50, 255, -1)
    return cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), (x, y), others
