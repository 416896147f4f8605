"""The engine's quality targets (issues 2 and 13), scored against analytic ground truth.

The scorer (``tests/distortion.py``) uses only the rendered per-pixel map and rays cast
at the analytic surfaces - not the engine's surfaces, meshes or solves. Measured
figures: ``.venv/bin/python tools/measure_warp.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import DEVELOPABLE, NON_DEVELOPABLE, SURFACES, get_surface
from adaproj_edge.geometry.rectangle import NEAR, Rect, inscribed_rectangle
from adaproj_edge.warp import reference
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.reference import REFERENCE
from tests.curvature_bound import curvature_bound
from tests.distortion import in_mask, lit_coverage, measure, visible_fraction
from tests.shown_maps import shown_map
from tests.warp.conftest import (
    CONTENT,
    LARGE_SUBJECTS,
    SMALL_SUBJECTS,
    distortion,
    subject_masks,
    surface,
    warped,
)

pytestmark = pytest.mark.slow

EXACT = 3e-4  # a developable surface smooth at the grid's scale: distortion-free
# non-developable surfaces, smooth (spheres, a bowl) and with detail (a curved crease,
# relief finer than the grid)
ALL_NON_DEVELOPABLE = (*NON_DEVELOPABLE, "cylinder-floor", "bumps")
# the large-subject line (issue 30): a large subject's size inconsistency at most 0.6x
# the conformal warp's, or 1.05x the least any angle-preserving map of its footprint
# can have, whichever is more; that bound is computed from the surface's Gaussian
# curvature over the footprint (tests/curvature_bound.py, docs/engine.md "Large
# subjects"), never from a warp's log size
LARGE_OF_CONFORMAL = 0.6
OF_BOUND = 1.05


def _subject(name: str, mode: str, mask: str | None, subject: str) -> tuple[float, float]:
    """Angle error and size inconsistency of the warp over the ``subject`` mask."""
    d = distortion(name, mode, mask)
    s = d.select(in_mask(d, subject_masks()[subject]))
    return s.angle_mean, s.size_std


@pytest.mark.parametrize("mode", ["conformal", "content"])
@pytest.mark.parametrize("name", DEVELOPABLE)
def test_developable_surfaces_are_distortion_free_per_pixel(name: str, mode: str) -> None:
    d = distortion(name, mode)
    assert d.angle_mean <= EXACT, d.angle_mean
    assert d.size_std <= EXACT, d.size_std


@pytest.mark.parametrize("mask", list(subject_masks()))
@pytest.mark.parametrize("name", DEVELOPABLE)
def test_developable_surfaces_stay_exact_with_a_salient_subject(name: str, mask: str) -> None:
    d = distortion(name, "content", mask)
    assert d.angle_mean <= EXACT and d.size_std <= EXACT, (d.angle_mean, d.size_std)


# the line for a developable surface on the displayed map: a wavy wall whose
# waves are two grid cells long is exact too once its columns are split finely enough
# (adaproj_edge/warp/adaptive.py: 5.2e-4 in angle when a column was split 8 times at
# most, 1.5e-4 at 12)
EXACT_DISPLAY = 5e-4


@pytest.mark.parametrize("mask", [None, "one-left", "half"])
@pytest.mark.parametrize("name", ["waves"])
def test_waves_two_grid_cells_long_are_followed(name: str, mask: str | None) -> None:
    assert get_surface(name).developable
    for mode in ("conformal", "content") if mask is None else ("content",):
        d = distortion(name, mode, mask)
        assert d.angle_mean <= EXACT_DISPLAY and d.size_std <= EXACT_DISPLAY, (
            mode,
            d.angle_mean,
            d.size_std,
        )


@pytest.mark.parametrize("name", [n for n in DEVELOPABLE if n != "plane"])
def test_standard_projection_is_visibly_worse(name: str) -> None:
    plain = distortion(name, "standard")
    fixed = distortion(name, "conformal")
    assert plain.angle_mean > 0.02 and plain.angle_mean > 20 * max(fixed.angle_mean, 1e-4)


CASES = [("standard", None), ("conformal", None)] + [("content", m) for m in subject_masks()]


@pytest.mark.parametrize(("mode", "mask"), CASES)
@pytest.mark.parametrize("name", list(SURFACES))
def test_every_mode_shows_all_content_without_folds(name: str, mode: str, mask: str | None) -> None:
    warp, m = warped(name, mode, mask)
    assert not np.isinf(m).any() and not np.isinf(warp.image_xy).any()
    assert np.isfinite(m).any(axis=2).sum() > 0.3 * m.shape[0] * m.shape[1]
    # NaN marks vertices without surface, never a vertex the surface reaches
    if mode != "standard":
        assert warp.depth is not None
        assert np.all(np.isfinite(warp.image_xy[np.isfinite(warp.depth)]))
    assert distortion(name, mode, mask).folds == 0
    assert visible_fraction(m, CONTENT) >= 0.9996


# the picture no smaller than the paper's: the content shows on at least 0.9x the lit
# projector pixels the paper-as-written warp's does (adaproj_edge/warp/reference.py:
# E' and the maximal inscribed rectangle in its domain, then eq. 8-9), with the same
# subject, computed here. On the half cylinder on a floor the content sits lower (0.78x:
# 0.475 of the lit pixels against 0.611; on the surface's area 0.97x). Not its size: the
# largest upright rectangle of our warp covers 0.740 (1.21x), its centre at projector
# pixel (627, 401), the middle of the view (the paper's, 0.611, is turned ~9 deg from
# the wall's vertical: its pinned grid corners set its orientation). Not the crease, the
# content step or the measure (both maps scored by lit_coverage on the same points).
# The centring loses it: of the rectangles at most 10 % narrower than the largest
# (adaproj_edge.geometry.rectangle.NEAR) the one nearest the flattened region's area
# centroid is taken, and the floor seen obliquely (31 % of that area, 17 % of the lit
# pixels) pulls the centroid down: the picture's centre goes to pixel (629, 508), 108 px
# below the middle of the view, onto the floor. Turning the content -6..+12 deg changes
# nothing (0.75-0.80x centred, 1.02-1.21x not). The paper-as-written warp placed by the
# same rule covers 0.490 here (ours 0.97x of it; like for like, every case >= 0.91x).
# Goals tried for the centring (one-left / half, against the real frames of
# tools/bench_real.py): the centroid of the lit pixels 0.89 / 1.24 (the corridor floor's
# picture 3x larger, its content-aware step folding, angle 0.016 -> 0.141); of area^(1-t)
# pixels^t, t = 0.3 0.86 / 0.89, 0.5 0.92 / 1.08, 0.6 0.90 / 1.14, 0.75 0.88 / 1.18 (each
# moving a room's picture across more of a depth jump, 2.3 -> 3.0 %, or the corridor
# floor's); of the surface's own area 0.80 / 0.82; the middle of the view (the lit
# pixels' centroid in the projector's frame, carried into the flattening) 0.92 / 1.09,
# every other case >= 0.90x, but room-beyond's picture 0.32 % across a jump (0 before),
# the corridor floor's angle 0.014 -> 0.016 (size 0.018 -> 0.015), and the tilted wall's
# picture 0.031-0.109 off the lit area's centroid (tests/warp/test_centring.py: <= 0.03;
# room-beyond's and desk-right's upright figures moved 0.1 -> 1.2 and 0.8 -> 0.9 deg, the
# harness's plane with them: read on one plane the new pictures are the more upright,
# 0.13 -> 0.08 and 0.83 -> 0.76); the largest when it is nearer the middle of the view,
# the corridor floor's angle 0.080. What the centred rectangle loses against the
# largest, in lit pixels (0.68-0.80 here) or pixels per area (0.71-0.99), does not tell
# this case from the real frames' (0.57-1.0, 0.59-1.0), nor do distances in the view
# (the corridor floor's centring moves its picture 63 -> 195 px from the middle, this
# one's 12 -> 109).
# On the fine corrugations the adaptive grid (100x60) left 0.63x the paper's lit pixels
# while its triangles took their shapes from their corners (chords cutting the waves'
# bends short: angle defects of 0.027 a vertex, a scale field of 0.82-1.13); with their
# sides measured on the development (adaproj_edge/geometry/developed.py) 0.93x
COVERAGE = 0.9
SMALLER = {"cylinder-floor": "centred on the area centroid, below the middle of the view"}


def _coverages(name: str, mask: str) -> tuple[float, float]:
    """The lit coverage of our content warp of ``name`` with subject ``mask``, and the
    paper-as-written warp's (as :mod:`adaproj_edge.warp.reference` places it)."""
    s = surface(name)
    paper = compute_warp(
        s,
        CONTENT,
        subject_masks()[mask],
        WarpSettings(mode="content", alternation="paper"),
        REFERENCE,
    )
    theirs = lit_coverage(shown_map(paper, s), s.points, CONTENT)
    ours = lit_coverage(warped(name, "content", mask)[1], s.points, CONTENT)
    return ours, theirs


@pytest.mark.parametrize("mask", ["one-left", "half"])
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(
            n, marks=pytest.mark.xfail(n in SMALLER, reason=SMALLER.get(n, ""), strict=True)
        )
        for n in SURFACES
    ],
)
def test_the_picture_covers_as_much_of_the_lit_surface_as_the_papers(name: str, mask: str) -> None:
    ours, theirs = _coverages(name, mask)
    assert ours >= COVERAGE * theirs, (ours, theirs)


@pytest.mark.parametrize("mask", ["one-left", "half"])
@pytest.mark.parametrize("name", sorted(SMALLER))
def test_where_centred_lower_it_covers_as_much_as_the_paper_centred_the_same_way(
    name: str, mask: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where the centring moves the picture off the largest rectangle (:data:`SMALLER`),
    the warp still lights as much as the paper-as-written warp placed by the same
    centring rule (its rectangle taken within :data:`NEAR` of the largest, as ours is):
    the warp's coverage, apart from where the picture is centred."""

    def centred(*args: Any, **kwargs: Any) -> Rect:
        return inscribed_rectangle(*args, **{**kwargs, "near": NEAR})  # (it passes 0)

    monkeypatch.setattr(reference, "inscribed_rectangle", centred)
    ours, theirs = _coverages(name, mask)
    assert ours >= COVERAGE * theirs, (ours, theirs)


CHOICES = ("content-aware", "flattened", "blend", "conformal flattened", "conformal")


# the full-grid guard judges the candidates as the per-pixel display shows them
# (adaproj_edge/warp/displayed.py): by the mesh alone, bumps with the quarter subject
# showed 1.02x the conformal warp's angle error
@pytest.mark.parametrize("mask", list(subject_masks()))
@pytest.mark.parametrize("name", ALL_NON_DEVELOPABLE)
def test_content_mode_is_never_worse_than_conformal_on_the_subject(name: str, mask: str) -> None:
    conf_angle, conf_size = _subject(name, "conformal", None, mask)
    angle, size = _subject(name, "content", mask, mask)
    assert angle <= conf_angle, (angle, conf_angle)
    assert size <= conf_size, (size, conf_size)
    warp, _ = warped(name, "content", mask)
    assert warp.meta["guard"]["choice"] in CHOICES


@pytest.mark.parametrize("mask", SMALL_SUBJECTS)
@pytest.mark.parametrize("name", NON_DEVELOPABLE)
def test_content_mode_keeps_a_subject_consistent(name: str, mask: str) -> None:
    conf_angle, conf_size = _subject(name, "conformal", None, mask)
    angle, size = _subject(name, "content", mask, mask)
    assert size <= 0.6 * conf_size, (size, conf_size)
    assert angle <= conf_angle, (angle, conf_angle)


@pytest.mark.parametrize("mask", LARGE_SUBJECTS)
@pytest.mark.parametrize("name", NON_DEVELOPABLE)
def test_content_mode_keeps_a_large_subject_consistent(name: str, mask: str) -> None:
    """The large-subject line: size <= max(0.6x the conformal warp's, 1.05x the curvature
    bound of the footprint the content warp gives the subject), angle <= 1.0x."""
    conf_angle, conf_size = _subject(name, "conformal", None, mask)
    angle, size = _subject(name, "content", mask, mask)
    _, shown = warped(name, "content", mask)
    bound = curvature_bound(
        shown, get_surface(name), surface(name).projector.K, subject_masks()[mask]
    )
    assert size <= max(LARGE_OF_CONFORMAL * conf_size, OF_BOUND * bound), (
        size / conf_size,
        bound / conf_size,
    )
    assert angle <= conf_angle, (angle, conf_angle)


def test_a_cat_photo_keeps_the_large_subject_line() -> None:
    """skimage's cat (chelsea) with a centred half-image subject, its content map made
    as ``adaproj warp --mode content --mask`` makes it (saliency, faces, the mask), on the
    convex sphere: the large-subject line. A false face on the cat's cheek (the face
    detector's scan image equalised globally) stretched the salient region to the
    image's edge, where no flattened candidate kept the conformal warp's angle error,
    and the guard kept the conformal warp: 1.00x its size spread on the subject, against
    0.77x now (the bound 0.76x; on the concave sphere it was 0.96x at 1.07x the angle
    error, now 0.88x at 1.00x). One surface: two warps of the photo cost ~8 s."""
    import cv2
    from skimage import data

    from adaproj_edge.content.contentmap import content_map_for

    name = "sphere-convex"
    image = cv2.cvtColor(data.chelsea(), cv2.COLOR_RGB2BGR)
    h, w = image.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    half = (((xx - 0.5 * w) / (0.4 * w)) ** 2 + ((yy - 0.5 * h) / (0.4 * h)) ** 2 <= 1).astype(
        np.float32
    )
    s, shape = surface(name), get_surface(name)
    cmap = content_map_for(image, half)
    measured = {}
    for mode, given in (("conformal", None), ("content", cmap)):
        m = shown_map(compute_warp(s, (w, h), given, WarpSettings(mode=mode)), s)
        d = measure(m, shape, s.projector.K)
        measured[mode] = (d.select(in_mask(d, half)), m)
    conf, (ours, shown) = measured["conformal"][0], measured["content"]
    bound = curvature_bound(shown, shape, s.projector.K, half)
    assert ours.size_std <= max(LARGE_OF_CONFORMAL * conf.size_std, OF_BOUND * bound), (
        ours.size_std / conf.size_std,
        bound / conf.size_std,
    )
    assert ours.angle_mean <= conf.angle_mean, (ours.angle_mean, conf.angle_mean)


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


# where the alternation cannot even out a large subject's size, the guard tries the
# content-aware warp with its size flattened (adaproj_edge/warp/flatten.py: the harmonic
# part of its log size over the subject removed by a holomorphic map, angles kept), and
# where neither it nor a blend toward the conformal warp is kept, the conformal warp
# flattened the same way. Measured (.venv/bin/python tools/measure_warp.py --surfaces
# sphere-concave,sphere-convex,bowl --masks quarter,half): 0.89x on sphere-concave
# quarter (a blend of the flattened warp), 0.94x on sphere-concave half (the conformal
# warp flattened), 0.74x on sphere-convex half (same), 0.65x on bowl quarter, 0.76x on
# bowl half (a blend); without the flattening 1.00x, 1.00x, 1.00x, 0.66x and 0.84x.
@pytest.mark.parametrize(
    ("name", "mask", "most", "source"),
    [
        ("sphere-concave", "quarter", 0.92, "flattened"),
        ("sphere-concave", "half", 0.97, "conformal flattened"),
        ("sphere-convex", "half", 0.8, "conformal flattened"),
        ("bowl", "quarter", 0.66, "flattened"),
        ("bowl", "half", 0.8, "flattened"),
    ],
)
def test_a_large_subjects_size_is_flattened(name: str, mask: str, most: float, source: str) -> None:
    conf_angle, conf_size = _subject(name, "conformal", None, mask)
    angle, size = _subject(name, "content", mask, mask)
    assert size <= most * conf_size, (size / conf_size, most)
    assert angle <= conf_angle, (angle, conf_angle)
    warp, _ = warped(name, "content", mask)
    guard = warp.meta["guard"]
    assert source in guard and guard[source]["size"] < guard["conformal"]["size"]
    assert source in (guard["choice"], guard.get("blend_of")), guard["choice"]


@pytest.mark.parametrize("name", NON_DEVELOPABLE)
def test_the_curvature_bound_is_below_what_small_subjects_reach(name: str) -> None:
    """A control: for a face-sized subject the curvature bound of its footprint is well
    below 0.6x the conformal warp's size inconsistency (0.10x-0.17x), and the engine,
    spending part of the conformal warp's angle error, reaches 0.6x there."""
    _, conf_size = _subject(name, "conformal", None, "face")
    _, shown = warped(name, "conformal")
    mask = subject_masks()["face"]
    bound = curvature_bound(shown, get_surface(name), surface(name).projector.K, mask)
    assert bound <= 0.3 * conf_size, bound / conf_size
