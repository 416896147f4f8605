"""What the projector shows: the current warp's maps, drawn into one reused frame
buffer, handed to the display loop (which marks the active faults on it and shows it
at each refresh, :mod:`adaproj_edge.app.display_loop`) and to the frame hook (replays
record what was shown)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from adaproj_edge.app.display_loop import DisplayLoop, Shown
from adaproj_edge.app.status import Faults, draw_status
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.arrays import Image
from adaproj_edge.errors import ImageError
from adaproj_edge.hal.clock import Clock
from adaproj_edge.render.frame import RemapMaps, render_frame
from adaproj_edge.render.photometry import GainMap, apply_gain
from adaproj_edge.warp.warpmap import Warp

FrameHook = Callable[[int, Image, dict[str, Any]], None]
"""Called with (time ns, frame shown, {"reason", "kind", "faults"}) for every frame."""


class Output:
    """The frame on the projector.

    Parameters
    ----------
    screen : DisplayLoop
        Where frames go (shown at the next refresh, or at once before the loop runs).
    clock : Clock
        Time stamps for the frame hook.
    faults : Faults
        Whose marks are drawn on every frame.
    telemetry : Telemetry
        Stage times ("render", "show") and the frames-shown counter.
    size : (width, height)
    on_frame : FrameHook, optional
    """

    def __init__(
        self,
        screen: DisplayLoop,
        clock: Clock,
        faults: Faults,
        telemetry: Telemetry,
        size: tuple[int, int],
        on_frame: FrameHook | None = None,
    ) -> None:
        self.screen = screen
        self.clock = clock
        self.faults = faults
        self.telemetry = telemetry
        self.on_frame = on_frame
        self.frame: Image = np.zeros((size[1], size[0], 3), np.uint8)
        self.warp: Warp | None = None
        self.maps: RemapMaps | None = None
        self.gain: GainMap | None = None
        self._good: Image | None = None
        self._canvas: Image | None = None
        self._kind = "plain"
        self.content = ""  # the name of the content shown (set by the runtime)
        self.frames = 0  # depth frames averaged into the surface of the warp shown

    @property
    def clean_frame(self) -> Image | None:
        """The last frame rendered, without the fault marks (None before any)."""
        return self._good

    def set(
        self, warp: Warp, maps: RemapMaps, gain: GainMap | None = None, frames: int = 0
    ) -> None:
        """The warp to show from now on, its maps, the brightness gain its frames carry
        (None: frames as rendered) and the depth frames averaged into the surface it was
        made for (0: none, a plain warp)."""
        self.warp, self.maps, self.gain, self.frames = warp, maps, gain, frames

    def render(self, image: Image, reason: str, kind: str, notify: bool = True) -> Image | None:
        """Draw ``image`` through the current maps and show it; returns the frame shown
        (None before any warp). Without ``notify`` the frame hook is left to the caller
        (:meth:`notify`)."""
        if self.maps is None:
            return None
        times = self.telemetry.times
        with times.timer("render"):
            frame = render_frame(image, self.maps, self._canvas)
            self._canvas = frame  # drawn into again next time
            if frame.ndim == 2:
                frame = np.asarray(cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR), np.uint8)
        if self.gain is not None:  # in place: the frame is drawn anew next time
            with times.timer("gain_apply"):
                frame = apply_gain(frame, self.gain, frame)
        self._good = frame
        self._kind = kind
        with times.timer("show"):
            out = self._show(frame)
        if notify:
            self.notify(out, reason, kind)
        return out

    def redraw(self) -> None:
        """Show the last good frame again with the current fault marks."""
        good = self._good
        if good is not None:
            self.notify(self._show(good), "status", "status")

    def notify(self, frame: Image, reason: str, kind: str) -> None:
        """Hand the frame shown to the frame hook."""
        if self.on_frame is not None:
            info = {"reason": reason, "kind": kind, "faults": self.faults.kinds()}
            self.on_frame(self.clock.now_ns(), frame, info)

    def png(self) -> bytes:
        """The frame shown now, as PNG bytes."""
        ok, enc = cv2.imencode(".png", self.frame)
        if not ok:
            raise ImageError("cannot encode the current frame as PNG")
        return bytes(enc.tobytes())

    def _show(self, frame: Image) -> Image:
        kinds = self.faults.kinds()
        out = draw_status(frame, kinds)
        self.frame = out
        self.telemetry.count("frames_shown")
        n = self.telemetry.counters["frames_shown"]
        shown = Shown(n, self._kind, self.warp, self.content, self.frames)
        self.screen.publish(frame, kinds, shown, self.clock.now_ns())
        return out
