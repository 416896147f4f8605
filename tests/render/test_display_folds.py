"""The device's display maps never fold (issue 13): the coarse-to-fine warp of every
analytic surface, drawn as the device draws it (``render/display_maps.py``, at 1/4 of
the frame and interpolated up), scored by ``tests/distortion.py`` against rays cast at
the analytic surface."""

from __future__ import annotations

import pytest

from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.analytic import SURFACES, get_surface
from adaproj_edge.render.display_maps import display_float_map
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.orientation import fold_count
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner
from tests.distortion import measure, visible_fraction
from tests.warp.conftest import CONTENT, subject_masks, surface

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("name", list(SURFACES))
def test_the_devices_display_maps_do_not_fold(name: str) -> None:
    s = surface(name)
    planner = WarpPlanner(s.projector, plan=PlanSettings(refine_factor=2))
    settings = WarpSettings(mode="content")
    cmap = ContentMap(subject_masks()["one-left"], CONTENT, settings.threshold)
    warp = planner.refine(s, cmap, settings, planner.content_free(s, CONTENT, settings))
    assert fold_count(warp) == 0
    shown = display_float_map(warp, 4)
    assert measure(shown, get_surface(name), s.projector.K).folds == 0
    assert visible_fraction(shown, CONTENT) >= 0.99
