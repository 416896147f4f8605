"""One button, three gestures.

- **press** (short, alone): reported once the double-press window has passed;
- **double** press: the second press within ``double_press_s`` of the first release;
- **long** press: held ``long_press_s`` or more (reported on release).
"""

from __future__ import annotations

from typing import Literal

from adaproj_edge.hal.button import ButtonEvent

Gesture = Literal["press", "double", "long"]


class Gestures:
    """Turns button events (with receive times, ns) into gestures.

    Parameters
    ----------
    double_press_s, long_press_s : float
        The double-press window and the long-press hold, seconds.
    """

    def __init__(self, double_press_s: float, long_press_s: float) -> None:
        self.double_ns = double_press_s * 1e9
        self.long_ns = long_press_s * 1e9
        self._press_ns: int | None = None
        self._single_ns: int | None = None

    def on_button(self, ev: ButtonEvent) -> Gesture | None:
        """A long or double press completed by ``ev``, else None (a single press waits
        for :meth:`tick`)."""
        if ev.pressed:
            self._press_ns = ev.receive_ns
            return None
        if self._press_ns is None:
            return None
        held = ev.receive_ns - self._press_ns
        press = self._press_ns
        self._press_ns = None
        if held >= self.long_ns:
            self._single_ns = None
            return "long"
        if self._single_ns is not None and press - self._single_ns <= self.double_ns:
            self._single_ns = None
            return "double"
        self._single_ns = ev.receive_ns
        return None

    def tick(self, now_ns: int) -> Gesture | None:
        """ "press" once a single press has waited out the double-press window."""
        if self._single_ns is not None and now_ns - self._single_ns > self.double_ns:
            self._single_ns = None
            return "press"
        return None
