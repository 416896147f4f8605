"""One button, six gestures.

- **press** (short, alone): reported once the double-press window has passed;
- **double** press: the second press within ``double_press_s`` of the first release;
- **long** press: held ``long_press_s`` or more (reported on release);
- **tap-hold**: a short press, then within ``double_press_s`` of its release a second
  press held ``long_press_s`` or more (reported on release; pauses or resumes a clip);
- **hold**: held ``hold_s`` or more (reported while still held, as soon as the time is
  up, so the user knows to let go; the release that follows is no gesture);
- **tap-hold-on** (``colour``): a short press, then within ``double_press_s`` of its
  release a second press held ``hold_s`` or more (reported like the hold).
"""

from __future__ import annotations

from typing import Literal

from adaproj_edge.hal.button import ButtonEvent

Gesture = Literal["press", "double", "long", "tap_hold", "hold", "colour"]


class Gestures:
    """Turns button events (with receive times, ns) into gestures.

    Parameters
    ----------
    double_press_s, long_press_s : float
        The double-press window and the long-press hold, seconds.
    hold_s : float
        The hold that starts the calibration, seconds (longer than ``long_press_s``).
    """

    def __init__(self, double_press_s: float, long_press_s: float, hold_s: float = 5.0) -> None:
        if hold_s <= long_press_s:
            raise ValueError(
                f"the hold ({hold_s:g} s) must outlast a long press ({long_press_s:g} s)"
            )
        self.double_ns = double_press_s * 1e9
        self.long_ns = long_press_s * 1e9
        self.hold_ns = hold_s * 1e9
        self._press_ns: int | None = None
        self._single_ns: int | None = None
        self._held = False  # the press down now was reported as a hold

    def on_button(self, ev: ButtonEvent) -> Gesture | None:
        """A long, tap-hold or double press completed by ``ev``, else None (a single
        press waits for :meth:`tick`)."""
        if ev.pressed:
            self._press_ns = ev.receive_ns
            self._held = False
            return None
        if self._press_ns is None or self._held:
            self._press_ns = None
            self._held = False
            return None
        held = ev.receive_ns - self._press_ns
        press = self._press_ns
        self._press_ns = None
        tapped = self._single_ns is not None and press - self._single_ns <= self.double_ns
        if held >= self.long_ns:
            self._single_ns = None
            return "tap_hold" if tapped else "long"
        if tapped:
            self._single_ns = None
            return "double"
        self._single_ns = ev.receive_ns
        return None

    def tick(self, now_ns: int) -> Gesture | None:
        """Return "hold" once the button has been down ``hold_s`` ("colour" when a short
        press came within the double-press window before); "press" once a single press
        has waited out the double-press window (not while a second press that began
        inside the window is still down: it may become a double or a tap-hold)."""
        if (
            self._press_ns is not None
            and not self._held
            and now_ns - self._press_ns >= self.hold_ns
        ):
            single = self._single_ns
            tapped = single is not None and self._press_ns - single <= self.double_ns
            self._held = True
            self._single_ns = None
            return "colour" if tapped else "hold"
        single, down = self._single_ns, self._press_ns
        if single is not None and down is not None and down - single <= self.double_ns:
            return None  # a second press is down: decided on its release
        if single is not None and now_ns - single > self.double_ns:
            self._single_ns = None
            return "press"
        return None
