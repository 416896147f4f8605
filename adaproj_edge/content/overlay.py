"""A picture of a content map over its image."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.content.contentmap import ContentMap


def to_gray(values: NDArray[np.floating]) -> NDArray[np.uint8]:
    """A map in [0, 1] as an 8-bit gray image (0 → black, 1 → white)."""
    v = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float32)), 0.0, 1.0)
    return np.asarray(np.round(v * 255.0), dtype=np.uint8)


def overlay(
    image_bgr: NDArray[np.uint8], cmap: ContentMap, alpha: float = 0.5
) -> NDArray[np.uint8]:
    """The image with C in false colour over it and the salient region (C >= T) outlined.

    Parameters
    ----------
    image_bgr : (h, w, 3) or (h, w) uint8
        The content the map was computed for.
    cmap : ContentMap
    alpha : float
        Weight of the false colour.

    Returns
    -------
    (h, w, 3) uint8
    """
    img = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    full = cmap.full_size()
    colour = cv2.applyColorMap(to_gray(full), cv2.COLORMAP_JET)
    out = cv2.addWeighted(img, 1.0 - alpha, colour, alpha, 0.0)
    salient = (full >= cmap.threshold).astype(np.uint8)
    contours, _ = cv2.findContours(salient, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    thickness = max(1, round(max(img.shape[:2]) / 300))
    cv2.drawContours(out, contours, -1, (255, 255, 255), thickness)
    return np.asarray(out, dtype=np.uint8)
