"""The engine's quality targets (issue 2), scored against analytic ground truth.

The scorer (``tests/distortion.py``) uses only the rendered per-pixel map and rays cast
at the analytic surfaces - not the engine's surfaces, meshes or solves.
"""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import DEVELOPABLE, NON_DEVELOPABLE, SURFACES
from tests.distortion import in_mask, visible_fraction
from tests.warp.conftest import CONTENT, distortion, subject_masks, warped

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("mode", ["conformal", "content"])
@pytest.mark.parametrize("name", DEVELOPABLE)
def test_developable_surfaces_are_distortion_free_per_pixel(name: str, mode: str) -> None:
    d = distortion(name, mode)
    assert d.angle_mean <= 0.005, d.angle_mean
    assert d.size_std <= 0.005, d.size_std


@pytest.mark.parametrize("name", DEVELOPABLE)
def test_developable_surfaces_stay_exact_with_a_salient_subject(name: str) -> None:
    d = distortion(name, "content", "one-left")
    assert d.angle_mean <= 0.005 and d.size_std <= 0.005, (d.angle_mean, d.size_std)


@pytest.mark.parametrize("name", [n for n in DEVELOPABLE if n != "plane"])
def test_standard_projection_is_visibly_worse(name: str) -> None:
    plain = distortion(name, "standard")
    fixed = distortion(name, "conformal")
    assert plain.angle_mean > 0.02 and plain.angle_mean > 20 * max(fixed.angle_mean, 1e-4)


@pytest.mark.parametrize("mask", ["one-left", "two-apart"])
@pytest.mark.parametrize("name", NON_DEVELOPABLE)
def test_content_mode_keeps_the_subject_consistent(name: str, mask: str) -> None:
    m = subject_masks()[mask]
    conf = distortion(name, "conformal")
    cont = distortion(name, "content", mask)
    conf_in = conf.select(in_mask(conf, m))
    cont_in = cont.select(in_mask(cont, m))
    assert cont_in.size_std <= 0.6 * conf_in.size_std, (cont_in.size_std, conf_in.size_std)
    assert cont_in.angle_mean <= 1.1 * conf_in.angle_mean, (cont_in.angle_mean, conf_in.angle_mean)


@pytest.mark.parametrize("mode", ["standard", "conformal", "content"])
@pytest.mark.parametrize("name", list(SURFACES))
def test_every_mode_shows_all_content_without_folds(name: str, mode: str) -> None:
    mask = "one-left" if mode == "content" else None
    warp, m = warped(name, mode, mask)
    assert not np.isinf(m).any() and not np.isinf(warp.image_xy).any()
    assert np.isfinite(m).any(axis=2).sum() > 0.3 * m.shape[0] * m.shape[1]
    # NaN marks vertices without surface, never a vertex the surface reaches
    if mode != "standard":
        assert warp.depth is not None
        assert np.all(np.isfinite(warp.image_xy[np.isfinite(warp.depth)]))
    assert distortion(name, mode, mask).folds == 0
    assert visible_fraction(m, CONTENT) >= 0.995


@pytest.mark.parametrize("name", NON_DEVELOPABLE)
def test_the_papers_alternation_barely_moves_the_subject_and_ours_does(name: str) -> None:
    m = subject_masks()["one-left"]
    conf = distortion(name, "conformal")
    paper = distortion(name, "content", "one-left", "paper")
    ours = distortion(name, "content", "one-left")
    ref = conf.select(in_mask(conf, m)).size_std
    paper_ratio = paper.select(in_mask(paper, m)).size_std / ref
    ours_ratio = ours.select(in_mask(ours, m)).size_std / ref
    assert paper.folds == 0 and paper_ratio > 0.8  # as the issue reports: 7-28 % at best
    assert ours_ratio < 0.6 * paper_ratio


def test_the_papers_alternation_keeps_the_boundary() -> None:
    free, _ = warped("bowl", "content")
    paper, _ = warped("bowl", "content", "one-left", "paper")
    assert paper.meta["iterations"] > 0
    boundary = np.isfinite(free.image_xy).all(axis=2)
    inner = np.zeros_like(boundary)
    inner[1:-1, 1:-1] = True  # the bowl fills the frame: the mesh boundary is the frame edge
    np.testing.assert_allclose(
        paper.image_xy[boundary & ~inner], free.image_xy[boundary & ~inner], atol=1e-6
    )
    # the interior moves, if only by a fraction of a pixel
    assert np.abs(paper.image_xy[inner] - free.image_xy[inner]).max() > 0.05
