"""User masks: a PNG, white where the content is important (paper §3.2, M_I)."""

from __future__ import annotations

import os

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import ImageError
from adaproj_edge.fileio import decode_image, read_image

Mask = NDArray[np.float32]


def mask_from_image(gray: NDArray[np.uint8], content_size: tuple[int, int], what: str) -> Mask:
    """A gray image of any size -> float32 mask (h, w) in [0, 1] at ``content_size`` (w, h)."""
    w, h = content_size
    if gray.ndim != 2:
        raise ImageError(f"{what}: a mask must be a single-channel image")
    mh, mw = gray.shape
    ratio_mask = mw / mh
    ratio_content = w / h
    if abs(np.log(ratio_mask / ratio_content)) > np.log(1.05):
        raise ImageError(
            f"{what} is {mw}x{mh} (aspect {ratio_mask:.3f}) but the content is {w}x{h} "
            f"(aspect {ratio_content:.3f}); a mask must have the content's aspect ratio"
        )
    resized = cv2.resize(gray, (w, h), interpolation=cv2.INTER_AREA)
    return (resized.astype(np.float32) / 255.0).clip(0.0, 1.0)


def load_mask(path: str | os.PathLike[str], content_size: tuple[int, int]) -> Mask:
    """Read a mask file and bring it to the content's size."""
    return mask_from_image(read_image(path, gray=True), content_size, str(path))


def decode_mask(data: bytes, content_size: tuple[int, int], what: str = "mask") -> Mask:
    """Decode mask bytes (PNG) and bring them to the content's size."""
    return mask_from_image(decode_image(data, what, gray=True), content_size, what)
