"""What the SMP server needs from the running device, and a stand-in for bring-up.

The device runtime (``app/``) implements :class:`DeviceRuntime`; ``adaproj link`` on
its own uses :class:`StandaloneDevice`, which shows the active image (a clip: its first
frame) letterboxed on the projector frame, without any warp.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD
from adaproj_edge.content.intake import read_content
from adaproj_edge.errors import AdaprojError, ContentError, ImageError
from adaproj_edge.warp.engine import MODES

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Settings:
    """How content is shown.

    Attributes
    ----------
    mode : str
        A warp mode (:data:`adaproj_edge.warp.engine.MODES`): ``"content"`` (distortion
        goes where the content map is low), ``"conformal"`` or ``"standard"`` (no warp).
    threshold : float
        Content-map level T in [0, 1] from which a region counts as important (eq. 5).
    """

    mode: str = "content"
    threshold: float = DEFAULT_THRESHOLD

    @classmethod
    def parse(cls, raw: dict[str, Any]) -> Settings:
        """Settings from a request's map; :class:`ContentError` names what is wrong."""
        unknown = set(raw) - {"mode", "threshold"}
        if unknown:
            raise ContentError(f"unknown settings {sorted(map(str, unknown))}: use mode, threshold")
        mode = raw.get("mode", cls.mode)
        if mode not in MODES:
            raise ContentError(f"mode must be one of {', '.join(MODES)}, not {mode!r}")
        threshold = raw.get("threshold", cls.threshold)
        if isinstance(threshold, bool) or not isinstance(threshold, (int, float)):
            raise ContentError("threshold must be a number in [0, 1]")
        if not 0.0 <= float(threshold) <= 1.0:
            raise ContentError(f"threshold must be in [0, 1], not {threshold}")
        return cls(str(mode), float(threshold))

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Content:
    """Content to show: files in the store, and how."""

    image: Path
    mask: Path | None = None
    settings: Settings = field(default_factory=Settings)


class DeviceRuntime(Protocol):
    """The running projector as the SMP server sees it.

    ``status`` returns a small map of plain values (text, numbers, lists, maps):
    at least ``state``, ``coverage`` (fraction of projector pixels on the surface, or
    ``None``), ``warp`` (the last warp's figures, or ``None``) and ``errors`` (recent
    error messages). ``activate`` raises an :class:`~adaproj_edge.errors.AdaprojError`
    to refuse content. ``frame_png`` is the frame the projector shows now, as PNG.
    All three are called from the link's thread (the one running
    :func:`~adaproj_edge.link.server.serve`), one at a time.
    """

    def status(self) -> dict[str, Any]: ...

    def activate(self, content: Content) -> None: ...

    def frame_png(self) -> bytes: ...


class StandaloneDevice:
    """The link without the projector pipeline: shows the image letterboxed, no warp.

    Parameters
    ----------
    width, height : int
        The projector frame size.
    """

    def __init__(self, width: int = 1280, height: int = 800) -> None:
        self.size = (width, height)
        self._frame: NDArray[np.uint8] = np.zeros((height, width, 3), np.uint8)
        self._content: Content | None = None
        self._errors: list[str] = []

    def status(self) -> dict[str, Any]:
        c = self._content
        return {
            "state": "showing" if c is not None else "idle",
            "image": c.image.name if c else None,
            "mask": c.mask.name if c and c.mask else None,
            "settings": c.settings.to_dict() if c else None,
            "frame": list(self.size),
            "coverage": None,
            "warp": None,
            "errors": self._errors[-5:],
        }

    def activate(self, content: Content) -> None:
        """Show ``content`` (checked as the runtime checks it: the image decodes, a mask
        has its aspect ratio)."""
        try:
            image = read_content(content.image, content.mask).image
        except AdaprojError as e:
            self._errors.append(str(e))
            raise
        self._frame = letterbox(image, self.size)
        self._content = content
        log.info("showing %s", content.image.name)

    def frame_png(self) -> bytes:
        ok, enc = cv2.imencode(".png", self._frame)
        if not ok:
            raise ImageError("cannot encode the current frame as PNG")
        return bytes(enc.tobytes())


def letterbox(image: NDArray[np.uint8], size: tuple[int, int]) -> NDArray[np.uint8]:
    """``image`` scaled to fit ``size`` (width, height), centred on black."""
    w, h = size
    ih, iw = image.shape[:2]
    s = min(w / iw, h / ih)
    nw, nh = max(1, round(iw * s)), max(1, round(ih * s))
    scaled = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_AREA)
    out = np.zeros((h, w, 3), np.uint8)
    x, y = (w - nw) // 2, (h - nh) // 2
    out[y : y + nh, x : x + nw] = scaled
    return out
