"""Picture-quality figures of the tests and the photometric bench, written here and not
taken from the code under test: PSNR, SSIM (Wang, Bovik, Sheikh, Simoncelli, "Image
quality assessment: from error visibility to structural similarity", IEEE TIP 2004;
Gaussian window of sigma 1.5, K1 = 0.01, K2 = 0.03, on 8-bit luma), and the reference
a viewer's picture is judged against: the content as it looks on a uniform white
surface in the same room, after one global gain.

The reference's gain ``k`` and the uniform room light ``c`` it adds are fitted by least
squares to the viewer's light (``k * content + c``): a uniform white wall shows the
content at one brightness over one veil of room light, whatever they are.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

GAMMA = 2.2


def to_light(values: NDArray[np.uint8]) -> NDArray[np.float64]:
    """8-bit values as linear light in [0, 1]."""
    return np.power(values.astype(np.float64) / 255.0, GAMMA)


def to_values(light: NDArray[np.float64]) -> NDArray[np.float64]:
    """Linear light as (unrounded) 8-bit values, clipped to [0, 255]."""
    return 255.0 * np.power(np.clip(light, 0.0, 1.0), 1.0 / GAMMA)


def reference(
    seen: NDArray[np.float64], content: NDArray[np.uint8], where: NDArray[np.bool_]
) -> NDArray[np.float64]:
    """``k * light(content) + c`` (H, W, 3) with ``k``, ``c`` fitted to the viewer's
    light ``seen`` (H, W, 3) over ``where`` (H, W)."""
    t = to_light(content)
    x = t[where].ravel()
    y = seen[where].ravel()
    a = np.stack([x, np.ones_like(x)], axis=1)
    (k, c), *_ = np.linalg.lstsq(a, y, rcond=None)
    out: NDArray[np.float64] = k * t + c
    return out


def psnr(a: NDArray[np.float64], b: NDArray[np.float64], where: NDArray[np.bool_]) -> float:
    """PSNR (dB) between two 8-bit-valued pictures (H, W, 3) over ``where``."""
    mse = float(np.mean((a[where] - b[where]) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def _luma(v: NDArray[np.float64]) -> NDArray[np.float64]:
    out: NDArray[np.float64] = v @ np.array([0.114, 0.587, 0.299])
    return out


def ssim(a: NDArray[np.float64], b: NDArray[np.float64], where: NDArray[np.bool_]) -> float:
    """Mean SSIM between the luma of two 8-bit-valued pictures (H, W, 3), over the
    pixels of ``where`` whose 3-sigma window lies inside it."""
    x, y = _luma(a), _luma(b)
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2

    def blur(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(cv2.GaussianBlur(v, (11, 11), 1.5), np.float64)

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    inside = cv2.erode(where.astype(np.uint8), np.ones((11, 11), np.uint8)) > 0
    return float(np.mean(s[inside]))


def scores(
    seen: NDArray[np.float64], content: NDArray[np.uint8], where: NDArray[np.bool_]
) -> tuple[float, float]:
    """(PSNR, SSIM) of the viewer's light ``seen`` against the content on uniform white."""
    ref = to_values(reference(seen, content, where))
    got = to_values(seen)
    return psnr(got, ref, where), ssim(got, ref, where)
