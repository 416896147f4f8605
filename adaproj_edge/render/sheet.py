"""Pictures side by side with captions (simulation pictures, contact sheets)."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from adaproj_edge.arrays import Image


def _bgr(img: Image) -> Image:
    return np.asarray(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img, np.uint8)


def captioned(img: Image, caption: str, height: int) -> Image:
    """``img`` scaled to ``height`` with a caption bar on top."""
    img = _bgr(img)
    scale = height / img.shape[0]
    body = cv2.resize(
        img, (max(1, round(img.shape[1] * scale)), height), interpolation=cv2.INTER_AREA
    )
    bar = np.full((28, body.shape[1], 3), 20, dtype=np.uint8)
    cv2.putText(
        bar, caption, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (235, 235, 235), 1, cv2.LINE_AA
    )
    return np.vstack([bar, body])


def row(images: Sequence[Image], captions: Sequence[str], height: int = 300) -> Image:
    """Captioned images side by side, with a thin gap."""
    parts: list[Image] = []
    for img, cap in zip(images, captions, strict=True):
        if parts:
            parts.append(np.full((height + 28, 6, 3), 0, dtype=np.uint8))
        parts.append(captioned(img, cap, height))
    return np.hstack(parts)


def _wrapped(lines: Sequence[str], width: int, scale: float, thick: int) -> list[str]:
    """``lines`` broken at spaces so that each fits ``width`` pixels."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    out: list[str] = []
    for line in lines:
        words = line.split() or [""]
        cur = words[0]
        for word in words[1:]:
            wider = cur + " " + word
            if cv2.getTextSize(wider, font, scale, thick)[0][0] > width:
                out.append(cur)
                cur = word
            else:
                cur = wider
        out.append(cur)
    return out


def titled(img: Image, lines: Sequence[str], scale: float = 0.55) -> Image:
    """``img`` under a bar holding ``lines`` of text (a title, a legend), left-aligned.

    Parameters
    ----------
    img : Image
        The picture, (h, w) or (h, w, 3) uint8.
    lines : sequence of str
        The text, a line each; keep them within the picture's width.
    scale : float
        Font scale (0.55: about 16 px high letters).

    Returns
    -------
    Image
        (bar + h, w, 3) uint8, BGR.
    """
    img = _bgr(img)
    step = round(48 * scale)
    lines = _wrapped(lines, img.shape[1] - 16, scale, 1)
    bar = np.full((step * len(lines) + round(12 * scale), img.shape[1], 3), 45, np.uint8)
    for i, text in enumerate(lines):
        y = step * (i + 1) - round(4 * scale)
        cv2.putText(
            bar, text, (8, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (245, 245, 245), 1, cv2.LINE_AA
        )
    return np.vstack([bar, img])


def stack(rows: Sequence[Image]) -> Image:
    """Rows one under the other, padded to the widest."""
    width = max(r.shape[1] for r in rows)
    padded = [np.pad(r, ((0, 6), (0, width - r.shape[1]), (0, 0))) for r in rows]
    return np.vstack(padded)


def text_page(lines: Sequence[str], size: tuple[int, int], scale: float = 1.0) -> Image:
    """Lines of white text on black, wrapped to the width, newest at the bottom.

    Parameters
    ----------
    lines : sequence of str
        Oldest first; those that do not fit are dropped from the top.
    size : (int, int)
        The page's width and height, pixels.
    scale : float
        Font scale (1.0: about 30 px high lines).

    Returns
    -------
    Image
        (height, width, 3) uint8, BGR.
    """
    w, h = size
    page = np.zeros((h, w, 3), np.uint8)
    font, thick = cv2.FONT_HERSHEY_SIMPLEX, max(1, round(2 * scale))
    step = round(36 * scale)
    margin = round(24 * scale)
    wrapped = _wrapped(lines, w - 2 * margin, scale, thick)
    fit = max(1, (h - 2 * margin) // step)
    for i, text in enumerate(wrapped[-fit:]):
        y = margin + step * (i + 1) - round(8 * scale)
        cv2.putText(page, text, (margin, y), font, scale, (255, 255, 255), thick, cv2.LINE_AA)
    return page
