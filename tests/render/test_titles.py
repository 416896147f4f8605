"""Pictures that explain themselves: a title bar above a picture, its lines wrapped to
the picture's width (render/sheet.py ``titled``)."""

from __future__ import annotations

import numpy as np

from adaproj_edge.render.sheet import titled


def test_a_title_bar_goes_above_the_picture_untouched() -> None:
    img = np.full((50, 400, 3), 7, np.uint8)
    out = titled(img, ["corner, as a viewer sees it"])
    assert out.shape[1:] == (400, 3) and out.shape[0] > 50
    assert np.array_equal(out[-50:], img)
    assert out[: out.shape[0] - 50].max() > 200  # the text, light on dark


def test_long_lines_wrap_to_the_width_instead_of_running_off() -> None:
    line = "Frames the device projected, by seconds from the start; plain: no pre-warp"
    wide = titled(np.zeros((10, 1200, 3), np.uint8), [line])
    narrow = titled(np.zeros((10, 200, 3), np.uint8), [line])
    assert narrow.shape[0] > wide.shape[0]  # more lines
    right = narrow[: narrow.shape[0] - 10, -6:]  # no letter reaches the right edge
    assert right.max() <= 60


def test_a_gray_picture_gets_a_colour_title() -> None:
    out = titled(np.zeros((20, 300), np.uint8), ["a", "b"])
    assert out.ndim == 3 and out.shape[0] > 20
