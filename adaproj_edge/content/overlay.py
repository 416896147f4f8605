"""A picture of a content map over its image."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.content.faces import FACE_DROP, FACE_SCALE

FACE_COLOUR = (255, 0, 255)
"""BGR colour of the faces' ellipses in the overlay (magenta)."""


def to_gray(values: NDArray[np.floating]) -> NDArray[np.uint8]:
    """A map in [0, 1] as an 8-bit gray image (0 → black, 1 → white)."""
    v = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float32)), 0.0, 1.0)
    return np.asarray(np.round(v * 255.0), dtype=np.uint8)


def overlay(
    image_bgr: NDArray[np.uint8], cmap: ContentMap, alpha: float = 0.5
) -> NDArray[np.uint8]:
    """The image with C in false colour over it, the salient region (C >= T) outlined
    in white and each detected face (``cmap.faces``) as a magenta ellipse.

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
    for x, y, bw, bh in np.asarray(cmap.faces, np.float64).reshape(-1, 4):
        centre = (round(x + bw / 2), round(y + bh / 2 + FACE_DROP * bh))
        axes = (max(1, round(FACE_SCALE[0] * bw)), max(1, round(FACE_SCALE[1] * bh)))
        cv2.ellipse(out, centre, axes, 0, 0, 360, FACE_COLOUR, thickness, cv2.LINE_AA)
    return np.asarray(out, dtype=np.uint8)
