"""What a viewer sees of a frame on a coloured, textured surface in a lit room, and what
the calibration camera captures of it: the simulated ground truth of the photometric
compensation.

Each projector pixel lights its surface point with the relative irradiance ``E``
(:func:`~adaproj_edge.geometry.irradiance.relative_irradiance`, scaled so the
surface's brightest lit part is 1); the surface returns ``albedo`` (blue, green, red
reflectance in [0, 1], as the projector sees the surface) of that light and of the
room's, ``ambient`` (a fraction of the projector's white at ``E = 1``). A Lambertian
surface looks the same from every direction, so the light seen of pixel ``x``,

    L(x) = albedo(x) * (E(x) * (value / 255) ** gamma + ambient),

is what every viewer sees there. The simulated camera is grey: it sees
``sum(PRIMARY_WEIGHTS * L)`` at ``level`` camera levels for ``L = 1``, with read and
shot noise (of the calibration simulator's camera, averaged over
:data:`CAMERA_PIXELS`), 8 bits and saturation, at 1/``scale`` of the frame (camera
pixels mapped to projector pixels already).

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import Float32Array, FloatArray
from adaproj_edge.errors import ImageError, InputError
from adaproj_edge.geometry.irradiance import Vignetting, relative_irradiance
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.reflectance import PRIMARY_WEIGHTS

CAPTURE_FRAMES: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("black", (0, 0, 0)),
    ("white", (255, 255, 255)),
    ("blue", (255, 0, 0)),
    ("green", (0, 255, 0)),
    ("red", (0, 0, 255)),
)
"""The photometric captures: the name and the projector's (blue, green, red) value."""


CAMERA_PIXELS = 4
"""Camera pixels averaged into one projector pixel of the captures (the camera sees
about one pixel per projector pixel; the captures are at 1/2 of the frame)."""


def albedo_from_image(image: NDArray[np.uint8], size: tuple[int, int]) -> Float32Array:
    """The reflectance (H, W, 3) in [0, 1] of an 8-bit picture (grey or BGR) of the
    surface as the projector sees it, resized to the frame's ``size`` (w, h)."""
    if image.ndim == 2:
        image = np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), np.uint8)
    if image.ndim != 3 or image.shape[2] not in (3, 4) or min(image.shape[:2]) < 1:
        raise ImageError(f"an albedo must be a grey or colour picture, got {image.shape}")
    bgr = image[..., :3]
    out = cv2.resize(bgr, size, interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
    return np.asarray(out, np.float32)


def scaled_irradiance(surface: Surface, vignetting: Vignetting | None = None) -> FloatArray:
    """The relative irradiance (H, W) of every frame pixel, 1 at the 99.9th percentile
    of the lit ones, 0 where no surface."""
    p = surface.projector
    dense = surface.dense()
    e = relative_irradiance(dense.points.astype(np.float64), p, p.pixel_grid(), vignetting)
    lit = np.isfinite(e)
    if not np.any(lit):
        return np.zeros(e.shape)
    out: FloatArray = np.where(lit, e / float(np.percentile(e[lit], 99.9)), 0.0)
    return np.minimum(out, 1.0)


def seen_light(
    frame: NDArray[np.uint8],
    albedo: NDArray[np.floating[Any]],
    irradiance: FloatArray,
    ambient: float,
    gamma: float = 2.2,
) -> FloatArray:
    """The light (H, W, 3) a viewer sees of ``frame`` (H, W, 3 BGR) on the surface."""
    if frame.shape[:2] != irradiance.shape or albedo.shape != (*irradiance.shape, 3):
        raise InputError(
            f"frame {frame.shape}, albedo {albedo.shape} and irradiance {irradiance.shape} differ"
        )
    lin = (np.arange(256) / 255.0) ** gamma
    sent = lin[frame] * irradiance[..., None] + ambient
    out: FloatArray = np.asarray(albedo, np.float64) * sent
    return out


def encode(light: FloatArray, gamma: float = 2.2) -> NDArray[np.uint8]:
    """Light in [0, 1] as 8-bit values (``255 * light ** (1 / gamma)``)."""
    v = 255.0 * np.power(np.clip(light, 0.0, 1.0), 1.0 / gamma)
    return np.rint(v).astype(np.uint8)


def simulated_captures(
    albedo: NDArray[np.floating[Any]],
    irradiance: FloatArray,
    ambient: float,
    rng: np.random.Generator,
    scale: int = 2,
    level: float = 200.0,
    gamma: float = 2.2,
) -> dict[str, FloatArray]:
    """The grey camera's captures of :data:`CAPTURE_FRAMES`, mapped to projector
    pixels at 1/``scale`` of the frame ((h, w) camera levels, NaN where no surface)."""
    h, w = irradiance.shape
    size = (max(w // scale, 1), max(h // scale, 1))
    none = cv2.resize((irradiance <= 0).astype(np.float32), size, interpolation=cv2.INTER_AREA)
    wt = np.asarray(PRIMARY_WEIGHTS, np.float64)
    out = {}
    for name, bgr in CAPTURE_FRAMES:
        frame = np.broadcast_to(np.asarray(bgr, np.uint8), (h, w, 3))
        grey = level * (seen_light(frame, albedo, irradiance, ambient, gamma) @ wt)
        small = cv2.resize(grey.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        sigma = np.sqrt(1.5**2 + 0.3 * np.maximum(small, 0.0)) / np.sqrt(CAMERA_PIXELS)
        noisy = np.clip(np.rint(small + sigma * rng.standard_normal(small.shape)), 0, 255)
        out[name] = np.where(none > 0, np.nan, noisy)
    return out
