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
    def upsampled(
        cls,
        small: NDArray[np.float32],
        size: tuple[int, int],
        scratch: NDArray[np.float32] | None = None,
    ) -> RemapMaps:
        """From a float map (h, w, 2) of the frame at reduced resolution, interpolated
        bilinearly to ``size`` (W, H) with pixel centres aligned (full-resolution pixel
        ``x`` sits at ``(x + 0.5) * w / W - 0.5``). NaN (no surface) shows black, and so
        do full-resolution pixels that take part of their value from one. ``scratch``
        (H, W, 2) float32, when given, holds the full-resolution float map on the way."""
        m = np.where(np.isfinite(small), small, np.float32(-1e4)).astype(np.float32)
        want = (size[1], size[0], 2)
        dst = scratch if scratch is not None and scratch.shape == want else None
        big = cv2.resize(m, size, dst=dst, interpolation=cv2.INTER_LINEAR)
        map1, map2 = cv2.convertMaps(big, cast(Any, None), cv2.CV_16SC2)
        return cls(np.asarray(map1), np.asarray(map2))


def render_frame(
    content: NDArray[np.uint8], maps: RemapMaps, out: NDArray[np.uint8] | None = None
) -> NDArray[np.uint8]:
    """The projector frame (H, W[, 3]) showing ``content`` through ``maps``; drawn into
    ``out`` when it has the frame's shape and type (a device reuses one buffer: a fresh
    frame every update costs page faults on every page)."""
    shape = (*maps.map1.shape[:2], *content.shape[2:])
    dst = out if out is not None and out.shape == shape and out.dtype == np.uint8 else None
    got = cv2.remap(
        content,
        maps.map1,
        maps.map2,
        dst=dst,
        interpolation=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    return np.asarray(got, dtype=np.uint8)
