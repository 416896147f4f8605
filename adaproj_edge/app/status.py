"""Faults the runtime shows: a small coloured square per fault in the frame's top-right
corner, the reason logged and listed in the device's status, cleared by the next good
input."""

from __future__ import annotations

import logging

import cv2

from adaproj_edge.arrays import Image

log = logging.getLogger(__name__)

MARK_COLOURS = {"camera": (0, 0, 255), "depth": (0, 160, 255), "range": (255, 0, 255)}
"""BGR colour of each fault's mark (others: yellow)."""


class Faults:
    """The current faults (kind -> message) and the recent error messages."""

    def __init__(self, keep_errors: int = 10) -> None:
        self.active: dict[str, str] = {}
        self.errors: list[str] = []
        self.keep_errors = keep_errors

    def __contains__(self, kind: object) -> bool:
        return kind in self.active

    def note_error(self, message: str) -> None:
        """Remember ``message`` among the recent errors."""
        self.errors = [*self.errors, message][-self.keep_errors :]

    def set(self, kind: str, message: str) -> bool | None:
        """Record fault ``kind``; returns None when nothing changed (same message), True
        for a new kind, False for a new message of a known kind."""
        if self.active.get(kind) == message:
            return None
        new = kind not in self.active
        self.active[kind] = message
        self.note_error(message)
        log.warning("%s: %s", kind, message)
        return new

    def clear(self, *kinds: str) -> list[str]:
        """Clear ``kinds``; returns those that were active."""
        gone = [k for k in kinds if k in self.active]
        for k in gone:
            del self.active[k]
            log.info("%s recovered", k)
        return gone

    def kinds(self) -> list[str]:
        """The active kinds, sorted."""
        return sorted(self.active)


def draw_status(frame: Image, faults: list[str]) -> Image:
    """``frame`` with a small square per fault in the top-right corner (none: as is)."""
    if not faults:
        return frame
    out = frame.copy()
    w = out.shape[1]
    for i, kind in enumerate(faults):
        x1 = w - 8 - i * 20
        colour = MARK_COLOURS.get(kind, (0, 255, 255))
        cv2.rectangle(out, (x1 - 12, 8), (x1, 20), colour, thickness=-1)
    return out
