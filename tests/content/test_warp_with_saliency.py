"""The saliency-driven warp against the conformal-only one, on non-developable surfaces.

The salient subject is what the content map marks salient (C >= T); its size
inconsistency is the standard deviation of log size of the displayed triangles whose
content lies in it, measured from the rendered map by ``tests/distortion.py`` (rays cast
at the analytic surface, independent of the engine).
"""

from __future__ import annotations

import numpy as np
import pytest
import skimage.data

from adaproj_edge.content.contentmap import content_map_for
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.geometry.analytic import NON_DEVELOPABLE, get_surface, simulate_surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from tests.distortion import in_mask, measure
from tests.shown_maps import shown_map


@pytest.mark.slow
@pytest.mark.parametrize("surface_name", NON_DEVELOPABLE)
@pytest.mark.parametrize("photo", ["coffee", "rocket"])
def test_saliency_warp_keeps_the_subject_more_consistent(
    model: SaliencyModel, photo: str, surface_name: str
) -> None:
    bgr = np.ascontiguousarray(getattr(skimage.data, photo)()[:, :, ::-1])
    h, w = bgr.shape[:2]
    cmap = content_map_for(bgr, model=model)
    subject = (cmap.full_size() >= cmap.threshold).astype(np.float64)
    assert 0.02 < subject.mean() < 0.5
    surface = simulate_surface(surface_name, step=8)
    spread = {}
    for mode, values in (("conformal", None), ("content", cmap.values)):
        warp = compute_warp(surface, (w, h), content_map=values, settings=WarpSettings(mode=mode))
        d = measure(shown_map(warp, surface), get_surface(surface_name), surface.projector.K)
        spread[mode] = d.select(in_mask(d, subject)).size_std
    assert spread["content"] < spread["conformal"], spread
