"""The last good warp, kept across restarts (``--state DIR``): shown at boot when it
fits the content and the frame, so a device that restarts comes back projecting."""

from __future__ import annotations

import logging
from pathlib import Path

from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.warp.warpmap import Warp

log = logging.getLogger(__name__)

LAST_WARP = "last-warp.npz"


class LastWarp:
    """Reads and writes ``DIR/last-warp.npz`` (atomically); ``None`` keeps nothing."""

    def __init__(self, state_dir: Path | None) -> None:
        self.state_dir = state_dir

    def load(self, projector: Projector, content_size: tuple[int, int]) -> Warp | None:
        """The kept warp if it fits ``content_size`` (w, h) and the projector's frame;
        None otherwise (an unreadable file is logged and ignored)."""
        if self.state_dir is None or not (self.state_dir / LAST_WARP).exists():
            return None
        try:
            warp = Warp.load(self.state_dir / LAST_WARP)
        except AdaprojError as e:
            log.warning("ignoring the last warp: %s", e)
            return None
        frame = (warp.projector.width, warp.projector.height)
        if warp.content_size != content_size or frame != (projector.width, projector.height):
            return None
        return warp

    def save(self, warp: Warp) -> None:
        """Keep ``warp``; a failure is logged, never raised (the device goes on)."""
        if self.state_dir is None:
            return
        try:
            self.state_dir.mkdir(parents=True, exist_ok=True)
            warp.save(self.state_dir / LAST_WARP)
        except (OSError, AdaprojError) as e:
            log.warning("cannot keep the last warp in %s: %s", self.state_dir, e)
