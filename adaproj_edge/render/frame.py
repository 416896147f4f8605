"""Warp map + content -> the projector frame (``cv2.remap``), black outside the content."""

from __future__ import annotations

from dataclasses import dataclass

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
