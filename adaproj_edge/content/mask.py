"""User masks: a PNG, white where the content is important (paper §3.2, M_I).

A mask may have any size as long as it has the content's aspect ratio (within 5 %); it
is resized to the content. Every way a mask can be unusable raises :class:`MaskError`
with a message naming the mask; callers keep the content usable without it.
"""

from __future__ import annotations

import os

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import ImageError, MaskError
from adaproj_edge.fileio import decode_image, read_image

Mask = NDArray[np.float32]

ASPECT_TOLERANCE = 1.05


def mask_from_image(
    gray: NDArray[np.uint8], content_size: tuple[int, int], what: str, kind: str = "mask"
) -> Mask:
    """A gray image of any size -> float32 mask (h, w) in [0, 1] at ``content_size`` (w, h);
    ``what`` names the image in messages and ``kind`` says what it is ("mask").

    Raises
    ------
    MaskError
        Not single-channel, or not the content's aspect ratio.
    """
    w, h = content_size
    if gray.ndim != 2:
        raise MaskError(f"{what}: a {kind} must be a single-channel image")
    mh, mw = gray.shape
    ratio_mask = mw / mh
    ratio_content = w / h
    if abs(np.log(ratio_mask / ratio_content)) > np.log(ASPECT_TOLERANCE):
        raise MaskError(
            f"{what} is {mw}x{mh} (aspect {ratio_mask:.3f}) but the content is {w}x{h} "
            f"(aspect {ratio_content:.3f}); a {kind} must have the content's aspect ratio"
        )
    resized = cv2.resize(gray, (w, h), interpolation=cv2.INTER_AREA)
    return (resized.astype(np.float32) / 255.0).clip(0.0, 1.0)


def decode_mask(data: bytes, content_size: tuple[int, int], what: str = "mask") -> Mask:
    """Decode mask bytes (PNG; JPEG is read too) and bring them to the content's size.

    Raises
    ------
    MaskError
        Unreadable, too large, or not the content's aspect ratio.
    """
    try:
        gray = decode_image(data, what, gray=True)
    except ImageError as e:
        raise MaskError(f"mask rejected: {e}") from None
    return mask_from_image(gray, content_size, what)


def load_mask(
    path: str | os.PathLike[str],
    content_size: tuple[int, int],
    what: str | None = None,
    kind: str = "mask",
) -> Mask:
    """Read a mask file and bring it to the content's size (``what`` names it in
    messages, default: its path; ``kind`` says what it is, default "mask": a
    ``--content-map`` file is read the same way).

    Raises
    ------
    MaskError
        The file cannot be read, or :func:`decode_mask` rejects it.
    """
    try:
        gray = read_image(path, gray=True)
    except ImageError as e:
        raise MaskError(f"{kind} rejected: {e}") from None
    return mask_from_image(gray, content_size, str(path) if what is None else what, kind)
