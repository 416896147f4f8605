"""Shared, cached warps of the analytic surfaces (each is computed once per session)."""

from __future__ import annotations

from functools import cache

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.geometry.analytic import get_surface, simulate_surface
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Warp
from tests.distortion import Distortion, measure
from tests.shown_maps import shown_map

CONTENT = (640, 400)


def subject_masks() -> dict[str, NDArray[np.float32]]:
    """Subjects: one standing left, two people apart, a face; a quarter and half of the
    image (centred ellipses)."""
    w, h = CONTENT
    yy, xx = np.mgrid[0:h, 0:w]

    def ellipse(cx: float, cy: float, rx: float, ry: float) -> NDArray[np.bool_]:
        return np.asarray(((xx - cx * w) / (rx * w)) ** 2 + ((yy - cy * h) / (ry * h)) ** 2 <= 1)

    return {
        "one-left": ellipse(0.3, 0.5, 0.14, 0.3).astype(np.float32),
        "two-apart": (ellipse(0.7, 0.55, 0.1, 0.25) | ellipse(0.25, 0.5, 0.1, 0.25)).astype(
            np.float32
        ),
        "face": ellipse(0.56, 0.42, 0.055, 0.09).astype(np.float32),
        "quarter": ellipse(0.5, 0.5, 0.28, 0.28).astype(np.float32),
        "half": ellipse(0.5, 0.5, 0.4, 0.4).astype(np.float32),
    }


# the subjects of each size: small ones, and ones covering a quarter and half the image
SMALL_SUBJECTS = ("one-left", "two-apart", "face")
LARGE_SUBJECTS = ("quarter", "half")


@cache
def surface(name: str) -> Surface:
    return simulate_surface(name)


@cache
def warped(
    name: str, mode: str, mask: str | None = None, alternation: str = "ours"
) -> tuple[Warp, NDArray[np.float32]]:
    s = surface(name)
    cmap = None if mask is None else subject_masks()[mask]
    settings = WarpSettings(mode=mode, alternation=alternation)  # type: ignore[arg-type]
    warp = compute_warp(s, CONTENT, cmap, settings)
    return warp, shown_map(warp, None if mode == "standard" else s)


@cache
def distortion(
    name: str, mode: str, mask: str | None = None, alternation: str = "ours"
) -> Distortion:
    _, m = warped(name, mode, mask, alternation)
    s = surface(name)
    return measure(m, get_surface(name), s.projector.K)
