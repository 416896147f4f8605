"""Warp map + content -> the projector frame (``cv2.remap``), black outside the content."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class RemapMaps:
    """Fixed-point maps for ``cv2.remap``, built once per warp, used for every frame."""

    map1: NDArray[np.int16]
    map2: NDArray[np.uint16]

    @classmethod
    def from_map(cls, map_xy: NDArray[np.float32]) -> RemapMaps:
        """From the float map (H, W, 2) of content coordinates, NaN where black."""
        m = np.where(np.isfinite(map_xy), map_xy, -1e4).astype(np.float32)
        map1, map2 = cv2.convertMaps(m[..., 0], m[..., 1], cv2.CV_16SC2)
        return cls(np.asarray(map1), np.asarray(map2))

    @classmethod
    def upsampled(cls, small: NDArray[np.float32], size: tuple[int, int]) -> RemapMaps:
        """From a float map (h, w, 2) of the frame at reduced resolution, interpolated
        bilinearly to ``size`` (W, H) with pixel centres aligned (full-resolution pixel
        ``x`` sits at ``(x + 0.5) * w / W - 0.5``). NaN (no surface) shows black, and so
        do full-resolution pixels that take part of their value from one."""
        m = np.where(np.isfinite(small), small, np.float32(-1e4)).astype(np.float32)
        big = cv2.resize(m, size, interpolation=cv2.INTER_LINEAR)
        map1, map2 = cv2.convertMaps(big, cast(Any, None), cv2.CV_16SC2)
        return cls(np.asarray(map1), np.asarray(map2))


def render_frame(content: NDArray[np.uint8], maps: RemapMaps) -> NDArray[np.uint8]:
    """The projector frame (H, W[, 3]) showing ``content`` through ``maps``."""
    out = cv2.remap(
        content,
        maps.map1,
        maps.map2,
        interpolation=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    return np.asarray(out, dtype=np.uint8)
