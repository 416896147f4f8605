"""The content map C: pixel-wise max of saliency and the user mask (paper §3.2)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import InputError

ContentMap = NDArray[np.float32]

DEFAULT_THRESHOLD = 0.67


def combine(
    content_size: tuple[int, int],
    saliency: NDArray[np.floating] | None = None,
    mask: NDArray[np.floating] | None = None,
) -> ContentMap | None:
    """``max(saliency, mask)`` at the content size; None when neither is given (uniform).

    Both inputs must already be (h, w) float maps in [0, 1] at ``content_size`` (w, h).
    """
    w, h = content_size
    maps = [m for m in (saliency, mask) if m is not None]
    if not maps:
        return None
    for m in maps:
        if m.shape != (h, w):
            raise InputError(f"content map of shape {m.shape} does not match the content {w}x{h}")
    out: ContentMap = np.asarray(maps[0], dtype=np.float32)
    for m in maps[1:]:
        out = np.maximum(out, np.asarray(m, dtype=np.float32))
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0).astype(np.float32)
