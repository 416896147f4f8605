"""A picture of the content's motion on the surface, stabilised and not: the content's
centre, horizontally and vertically on the surface (millimetres from its mean), over a
few seconds of a replay (``handheld.png`` in a replay's output)."""

from __future__ import annotations

import cv2
import numpy as np

from adaproj_edge.arrays import FloatArray, Image

ON = (80, 200, 80)  # BGR: stabilised
OFF = (60, 60, 230)  # not stabilised
W, H = 900, 220


def _panel(t: FloatArray, on: FloatArray, off: FloatArray, title: str) -> Image:
    """One axis of motion: ``on`` and ``off`` (K,) mm against ``t`` (K,) s."""
    img = np.full((H, W, 3), 255, np.uint8)
    x0, x1, y0, y1 = 60, W - 15, 30, H - 30
    both = np.concatenate([on - np.nanmean(on), off - np.nanmean(off)])
    span = max(1.0, float(np.nanmax(np.abs(both))) * 1.1) if np.isfinite(both).any() else 1.0
    cv2.rectangle(img, (x0, y0), (x1, y1), (200, 200, 200), 1)
    mid = (y0 + y1) // 2
    cv2.line(img, (x0, mid), (x1, mid), (225, 225, 225), 1)

    def px(tt: FloatArray, v: FloatArray) -> np.ndarray:
        u = x0 + (tt - t[0]) / max(float(t[-1] - t[0]), 1e-9) * (x1 - x0)
        w = mid - v / span * (y1 - y0) / 2
        pts = np.stack([u, w], axis=1)
        return np.round(pts[np.all(np.isfinite(pts), axis=1)]).astype(np.int32)

    for v, colour in ((off, OFF), (on, ON)):
        pts = px(t, v - np.nanmean(v))
        if len(pts) > 1:
            cv2.polylines(img, [pts], False, colour, 2, cv2.LINE_AA)
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(img, title, (x0, 20), font, 0.5, (40, 40, 40), 1, cv2.LINE_AA)
    for val, y in ((span, y0), (-span, y1)):
        cv2.putText(img, f"{val:+.1f} mm", (2, y + 5), font, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    cv2.putText(img, f"{t[0]:.1f} s", (x0, H - 10), font, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    cv2.putText(img, f"{t[-1]:.1f} s", (x1 - 45, H - 10), font, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    return img


def motion_plot(t_s: FloatArray, on: FloatArray, off: FloatArray, seconds: float = 3.0) -> Image:
    """The picture: ``on`` and ``off`` (K, 3) positions (mm) of the content's centre on
    the surface at times ``t_s`` (K,), over the ``seconds`` with the most refreshes
    scored (a still stretch, usually): horizontal motion above, vertical below,
    stabilised in green, not stabilised in red."""
    if len(t_s) < 2:
        raise ValueError("nothing to plot")
    start = t_s[0]
    counts = [np.sum((t_s >= a) & (t_s < a + seconds)) for a in t_s]
    start = t_s[int(np.argmax(counts))]
    sel = (t_s >= start) & (t_s < start + seconds)
    t = t_s[sel]
    # horizontal: the surface's x (W); vertical: y (W, down)
    top = _panel(t, on[sel, 0], off[sel, 0], "content centre, horizontal (mm)")
    bottom = _panel(t, on[sel, 1], off[sel, 1], "content centre, vertical (mm)")
    key = np.full((26, W, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(key, "stabilised", (60, 18), font, 0.5, ON, 2, cv2.LINE_AA)
    cv2.putText(key, "not stabilised", (200, 18), font, 0.5, OFF, 2, cv2.LINE_AA)
    return np.vstack([key, top, bottom])
