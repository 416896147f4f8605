"""The device's content maps: one saliency session for stills and clips, warmed before
a clip plays."""

from __future__ import annotations

import numpy as np

from adaproj_edge.app.content import Item, SaliencyMaps
from adaproj_edge.content.model import SaliencyModel


def test_stills_and_clips_share_one_session_warmed_for_the_clip() -> None:
    maps = SaliencyMaps()
    image = np.zeros((40, 64, 3), np.uint8)
    image[10:30, 20:40] = (0, 0, 255)
    still = maps("a", image, None, 0.67)
    model = maps.model()
    assert isinstance(model, SaliencyModel) and still.values.max() > 0
    assert not model._warm  # a still does not warm (its first map waits anyway)
    item = Item("clip", image, None)
    clip = maps.clip_maps(item)
    assert maps.model() is model  # no second session
    assert model._warm
    assert clip.model is model
