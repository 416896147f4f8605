"""The content-aware warp of a video: quality per frame and coherence in time, against
analytic ground truth (tests/distortion.py), on a synthetic clip with a subject moving
across a textured background (tests/content/clips.py).

The clip's content maps come from the real chain (the saliency model through
:class:`TemporalContentMap`); the warp path is the device's: the planner (coarse to
fine for stills, a clip's frames on the full grid), warm-started, one refinement per
frame with ``frame_dt``. Its yardsticks get the same content map of each frame: the
fixed content-free warp (the paper's way for video) and an independent full-grid solve
of the frame (``compute_warp``, cold).

The issue asks for the subject's size inconsistency within 1.3x of an independent full
solve on every frame. Measured (``tools/measure_video.py [--low-pass|--line-fit]``; 45
frames; the subject moving right at 180 px/s, stopping at frame 22, at 270 px/s,
turning back at frame 22), worst frame of each clip:

- the device's defaults (full grid, 3 steps, band 0.05, the line fit over 0.4 s with
  the turn test and 0.2 of the residual): 1.23x, 1.23x, 1.23x, 1.29x (frame 27); RMS
  acceleration 5.1x lower than the independent solves' on the moving subject;
  asserted at 1.3x on every frame of the four clips;
- the plain line fit (:data:`LINE_FIT`): 1.25x, 1.25x, 1.23x, 1.33x (frame 32: the
  line overshoots the turn);
- the defaults before issue 15 (:data:`LOW_PASS`: coarse grid, 2 steps, two-stage
  low-pass of 50 ms): 1.41x, 1.41x, 1.32x, 1.41x (the filter's lag and the coarse
  grid's cold first frame).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cache

import numpy as np
import pytest
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.content.faces import FaceDetector
from adaproj_edge.content.facetrack import FaceTracker
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.content.temporal import TemporalContentMap
from adaproj_edge.geometry.analytic import get_surface
from adaproj_edge.render.display_maps import display_float_map
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.orientation import fold_count
from adaproj_edge.warp.planner import ContentFreeWarp, PlanSettings, WarpPlanner, compute_warp
from adaproj_edge.warp.temporal import (
    LINE_FIT,
    LOW_PASS,
    GradedContentMap,
    TemporalWarpSettings,
    WarpSmoother,
)
from adaproj_edge.warp.warpmap import Grid, Warp
from tests.content.clips import face_frame, subject_frame
from tests.distortion import Distortion, in_mask, measure
from tests.warp.conftest import surface as simulate_surface  # cast once per surface

SURFACE = "sphere-concave"
SIZE = (640, 360)
FPS = 30.0
FRAMES = 45  # 1.5 s
SETTINGS = WarpSettings(mode="content", max_iterations=6)  # the device's
DEVICE_PLAN = PlanSettings(refine_factor=2, warm_start=True)


@dataclass
class Played:
    """A clip played through the temporal warp, beside its yardsticks."""

    content_free: ContentFreeWarp
    masks: list[NDArray[np.bool_]]
    shown: list[Warp]
    independent: list[Warp]  # compute_warp of each frame (full grid, cold)


def planner(plan: PlanSettings = DEVICE_PLAN) -> WarpPlanner:
    return WarpPlanner(simulate_surface(SURFACE).projector, plan=plan, cache=WarpCache())


MOTIONS: dict[str, Callable[[int], tuple[NDArray[np.uint8], NDArray[np.bool_]]]] = {
    "right": lambda i: subject_frame(i, SIZE, 6.0),  # 180 px/s across a 640 px frame
    "still": lambda i: subject_frame(i, SIZE, 0.0),
    "stops": lambda i: subject_frame(min(i, 22), SIZE, 6.0),  # halfway, at 0.73 s
    "fast": lambda i: subject_frame(i, SIZE, 9.0, start=0.15),  # 270 px/s
    "turns": lambda i: subject_frame(22 - abs(i - 22), SIZE, 6.0),  # back at frame 22
}
"""Frame i of each test clip and its subject's true mask."""


@cache
def played(motion: str, temporal: TemporalWarpSettings | None = None) -> Played:
    """``motion``'s clip played with ``temporal`` (None: the device's defaults)."""
    surface = simulate_surface(SURFACE)
    device = planner(DEVICE_PLAN if temporal is None else replace(DEVICE_PLAN, temporal=temporal))
    cf = device.content_free(surface, SIZE, SETTINGS)
    maps = TemporalContentMap(SIZE, SaliencyModel())
    out = Played(cf, [], [], [])
    for i in range(FRAMES):
        image, mask = MOTIONS[motion](i)
        cmap = maps.update(image)
        out.masks.append(mask)
        out.shown.append(device.refine(surface, cmap, SETTINGS, cf, frame_dt=1 / FPS))
        if motion != "still":
            out.independent.append(compute_warp(surface, SIZE, cmap, SETTINGS))
    return out


def subject_size(warp: Warp | Distortion, mask: NDArray[np.bool_]) -> float:
    """The subject's size inconsistency on the true surface, in what the display maps
    draw (ground truth: rays cast at the analytic surface)."""
    d = warp if isinstance(warp, Distortion) else drawn(warp)
    return d.select(in_mask(d, mask.astype(np.float32))).size_std


def drawn(warp: Warp) -> Distortion:
    """The distortion of what the display maps draw for ``warp``, fold-free."""
    surface = simulate_surface(SURFACE)
    d = measure(display_float_map(warp, 4), get_surface(SURFACE), surface.projector.K)
    assert d.folds == 0
    return d


def acceleration(warps: list[Warp]) -> float:
    """RMS second difference of the vertices' content positions over frames (px)."""
    xy = np.stack([w.image_xy for w in warps])
    acc = xy[2:] - 2 * xy[1:-1] + xy[:-2]
    return float(np.sqrt(np.mean(acc[np.isfinite(acc)] ** 2)))


def size_ratios(p: Played) -> tuple[FloatArray, FloatArray]:
    """Per frame, the subject's size inconsistency in the shown warp over the
    independent full solve's and over the content-free warp's."""
    fixed = drawn(p.content_free.warp)  # the same warp on every frame: measured once
    full, free = [], []
    for shown, independent, mask in zip(p.shown, p.independent, p.masks, strict=True):
        ours = subject_size(shown, mask)
        full.append(ours / subject_size(independent, mask))
        free.append(ours / subject_size(fixed, mask))
    return np.array(full), np.array(free)


@pytest.mark.slow
@pytest.mark.parametrize("motion", ["right", "stops", "fast", "turns"])
def test_moving_subject_keeps_its_size_on_every_frame(motion: str) -> None:
    full, free = size_ratios(played(motion))  # the device's defaults
    assert np.all(full <= 1.3), np.round(full, 3)
    if motion != "fast":  # there the independent solves themselves are 0.73x
        assert np.all(free <= 0.6), np.round(free, 3)


@pytest.mark.slow
def test_moving_subject_moves_the_warp_smoothly() -> None:
    p = played("right")
    ours, independent = acceleration(p.shown), acceleration(p.independent)
    assert ours * 5 <= independent, (ours, independent)
    assert all(fold_count(w) == 0 for w in p.shown)


@pytest.mark.slow
def test_still_scene_gives_a_still_warp_after_a_second() -> None:
    p = played("still")
    xy = np.stack([w.image_xy for w in p.shown])
    motion = np.linalg.norm(np.diff(xy, axis=0), axis=-1)  # (frames - 1, R, C)
    after = motion[round(FPS) - 1 :]
    assert np.nanmax(after) < 0.05, np.nanmax(after, axis=(1, 2))
    assert np.isfinite(xy[0]).sum() == np.isfinite(xy[-1]).sum()
    # and it is the content-aware warp, not the content-free one
    cf = p.content_free.warp.image_xy
    assert np.nanmax(np.abs(xy[-1] - cf)) > 5.0


def _warp(xy: FloatArray) -> Warp:
    cf = planner().content_free(simulate_surface(SURFACE), SIZE, SETTINGS).warp
    return replace(cf, image_xy=xy)


def test_smoother_moves_without_overshoot_and_settles() -> None:
    base = _warp(np.zeros((21, 21, 2)))
    a = base.grid_uv * 0.4 + 10.0
    b = a + 8.0
    smoother = WarpSmoother(LOW_PASS)
    source = object()
    first = smoother.smooth(replace(base, image_xy=a), source, 1 / FPS)
    assert not first.meta["smoothed"] and np.array_equal(first.image_xy, a)
    path = [smoother.smooth(replace(base, image_xy=b), source, 1 / FPS) for _ in range(40)]
    offsets = np.array([float(np.mean(w.image_xy - a)) for w in path])
    assert np.all(np.diff(offsets) >= 0) and offsets.max() <= 8.0  # no overshoot
    assert 0.0 < offsets[0] < 2.0  # a step is eased in, not taken at once
    assert offsets[-1] == pytest.approx(8.0, abs=1e-3) and path[-1].meta["smoothed"]
    # another source (a new pose) is shown as it comes
    other = smoother.smooth(replace(base, image_xy=a), object(), 1 / FPS)
    assert np.array_equal(other.image_xy, a) and not other.meta["smoothed"]


def test_smoother_gain_follows_the_frame_interval() -> None:
    s = TemporalWarpSettings(time_constant_s=0.035)
    assert s.gain(1 / 30) == pytest.approx(1 - np.exp(-1 / 30 / 0.035))
    assert s.gain(1 / 15) > s.gain(1 / 30) > s.gain(1 / 60) > 0
    assert s.gain(0.0) == 1.0 and TemporalWarpSettings(time_constant_s=0.0).gain(0.1) == 1.0


def test_smoother_follows_a_steady_motion_without_lag_and_settles() -> None:
    base = _warp(np.zeros((21, 21, 2)))
    a = base.grid_uv * 0.4 + 10.0
    smoother = WarpSmoother(LINE_FIT)  # the plain line: no turns, no residual
    source = object()
    first = smoother.smooth(replace(base, image_xy=a), source, 1 / FPS)
    assert not first.meta["smoothed"] and np.array_equal(first.image_xy, a)
    # 2 px a frame, with +-0.5 px of jitter: followed where it is, the jitter averaged
    jitter = [0.5 * (-1) ** n for n in range(1, 41)]
    moving = [a + 2.0 * n + j for n, j in enumerate(jitter, 1)]
    path = [smoother.smooth(replace(base, image_xy=xy), source, 1 / FPS) for xy in moving]
    offsets = np.array([float(np.mean(w.image_xy - a)) for w in path])
    late = np.arange(1, 41)[15:]
    assert np.all(np.abs(offsets[15:] - 2.0 * late) < 0.1)  # no lag
    acc_in = np.diff([2.0 * n + j for n, j in enumerate(jitter, 1)], 2)
    assert np.sqrt(np.mean(np.diff(offsets[15:], 2) ** 2)) < 0.1 * np.sqrt(np.mean(acc_in**2))
    # it stops: a line fitted to a turn overshoots for a while, then settles exactly
    b = moving[-1]
    stopped = [smoother.smooth(replace(base, image_xy=b), source, 1 / FPS) for _ in range(20)]
    over = np.array([float(np.mean(w.image_xy - b)) for w in stopped])
    assert np.all(over <= 0.3 * 2.0 * 0.4 * FPS)  # < 30 % of the window's travel
    assert np.allclose(stopped[-1].image_xy, b, atol=1e-9) and stopped[-1].meta["smoothed"]
    # another source (a new pose) is shown as it comes
    other = smoother.smooth(replace(base, image_xy=a), object(), 1 / FPS)
    assert np.array_equal(other.image_xy, a) and not other.meta["smoothed"]


@pytest.mark.parametrize("fps", [15.0, 30.0, 60.0])
def test_smoother_window_is_clip_time(fps: float) -> None:
    base = _warp(np.zeros((21, 21, 2)))
    a = base.grid_uv * 0.4 + 10.0
    smoother = WarpSmoother(LINE_FIT)
    source = object()
    for _ in range(5):
        smoother.smooth(replace(base, image_xy=a), source, 1 / fps)
    steps = [smoother.smooth(replace(base, image_xy=a + 8.0), source, 1 / fps) for _ in range(40)]
    settled = [np.allclose(w.image_xy, a + 8.0, atol=1e-9) for w in steps]
    frames = round(0.4 * fps)  # then the last ``a`` has left the window
    assert all(settled[frames:]) and not settled[frames - 1]
    # no time between frames (a jump): shown as it comes
    jump = smoother.smooth(replace(base, image_xy=a), source, 0.0)
    assert np.array_equal(jump.image_xy, a) and not jump.meta["smoothed"]


def test_smoother_takes_a_turn_with_a_shorter_window_and_not_a_steady_motion() -> None:
    base = _warp(np.zeros((21, 21, 2)))
    a = base.grid_uv * 0.4 + 10.0
    jitter = [0.3 * (-1) ** n for n in range(45)]
    # 2 px a frame to frame 22, then back (the test clip's turn), with jitter
    path = [2.0 * (22 - abs(n - 22)) + j for n, j in enumerate(jitter)]
    errors = {}
    for name, settings in (("turns", TemporalWarpSettings()), ("line", LINE_FIT)):
        smoother, source = WarpSmoother(settings), object()
        shown = [
            float(
                np.mean(
                    smoother.smooth(replace(base, image_xy=a + x), source, 1 / FPS).image_xy - a
                )
            )
            for x in path
        ]
        errors[name] = np.abs(np.array(shown) - [2.0 * (22 - abs(n - 22)) for n in range(45)])
        if name == "turns":
            assert smoother.turns > 0
    # the line overshoots the turn for a window; seen as a turn (4 frames after it,
    # here), the path is followed sooner
    assert errors["turns"][22:36].mean() < 0.6 * errors["line"][22:36].mean()
    assert errors["turns"][26:36].max() < 0.5 * errors["line"][26:36].max()
    # a turn window shorter than a frame: the line through the newest two
    smoother, source = WarpSmoother(TemporalWarpSettings(turn_window_s=0.01)), object()
    for x in path:
        shown_xy = smoother.smooth(replace(base, image_xy=a + x), source, 1 / FPS).image_xy
        assert np.isfinite(shown_xy).all()
    assert smoother.turns > 0
    # a steady motion (the same jitter) is no turn: the line, the residual's share added
    smoother, source = WarpSmoother(TemporalWarpSettings()), object()
    steady = [
        smoother.smooth(replace(base, image_xy=a + 2.0 * n + j), source, 1 / FPS)
        for n, j in enumerate(jitter)
    ]
    assert smoother.turns == 0
    offsets = np.array([float(np.mean(w.image_xy - a)) for w in steady])
    assert np.all(np.abs(offsets[15:] - 2.0 * np.arange(15, 45)) < 0.1)  # no lag


def test_temporal_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="steps"):
        TemporalWarpSettings(steps=0)
    with pytest.raises(ValueError, match="band"):
        TemporalWarpSettings(band=0.5)
    with pytest.raises(ValueError, match="window_s"):
        TemporalWarpSettings(window_s=-1.0)
    with pytest.raises(ValueError, match="time_constant_s"):
        TemporalWarpSettings(time_constant_s=-1.0)
    with pytest.raises(ValueError, match="turn_ratio"):
        TemporalWarpSettings(turn_ratio=-1.0)
    with pytest.raises(ValueError, match="turn_window_s"):
        TemporalWarpSettings(turn_window_s=0.0)
    with pytest.raises(ValueError, match="residual_gain"):
        TemporalWarpSettings(residual_gain=1.5)


def test_graded_weights_rise_smoothly_through_the_threshold() -> None:
    values = np.tile(np.linspace(0, 1, 101, dtype=np.float32), (3, 1))
    cmap = ContentMap(values, (101, 3), 0.6)
    xy = np.stack([np.linspace(0, 100, 401), np.ones(401)], axis=1)
    c = cmap.sample(xy)
    graded = GradedContentMap.of(cmap, 0.1).weights(xy)
    assert np.all(np.diff(graded) >= 0) and graded.min() == 0.0 and graded.max() == 1.0
    assert np.all(graded[c <= 0.5] == 0) and np.all(graded[c >= 0.7] == 1)
    assert np.all((graded > 0) & (graded < 1) == ((c > 0.5) & (c < 0.7)))
    assert np.array_equal(GradedContentMap.of(cmap, 0.0).weights(xy), cmap.weights(xy))


def test_video_frames_take_the_bounded_steps_from_a_warm_start() -> None:
    surface = simulate_surface(SURFACE)
    plan = replace(DEVICE_PLAN, temporal=TemporalWarpSettings(steps=1))
    device = planner(plan)
    cf = device.content_free(surface, SIZE, SETTINGS)
    cmap = TemporalContentMap(SIZE, SaliencyModel()).update(subject_frame(0, SIZE)[0])
    first = device.refine(surface, cmap, SETTINGS, cf, frame_dt=1 / FPS)
    assert first.meta["iterations"] > 1 and not first.meta["smoothed"]
    moved = TemporalContentMap(SIZE, SaliencyModel()).update(subject_frame(8, SIZE)[0])
    second = device.refine(surface, moved, SETTINGS, cf, frame_dt=1 / FPS)
    assert second.meta["iterations"] == 1 and second.meta["smoothed"]
    # the same map again: refined on, warm, until no vertex moves more than settle_px,
    # then no step: the refined warp held (the filter still converges)
    again = [device.refine(surface, moved, SETTINGS, cf, frame_dt=1 / FPS) for _ in range(12)]
    steps = [w.meta["iterations"] for w in again]
    assert steps[0] >= 1 and 0 in steps, steps
    held = steps.index(0)
    assert all(s >= 1 for s in steps[:held]) and not any(steps[held:]), steps
    assert all(w.meta["held"] for w in again[held:]) and device.smoother.settled
    assert device.smoother.last_move <= TemporalWarpSettings().settle_px
    assert device.smoother.holds == len(steps) - held
    nudged = replace(moved, values=np.clip(moved.values + 0.02, 0, 1))
    assert device.refine(surface, nudged, SETTINGS, cf, frame_dt=1 / FPS).meta["iterations"] == 1
    device.forget()  # no past: cold again, shown as solved
    cold = device.refine(surface, moved, SETTINGS, cf, frame_dt=1 / FPS)
    assert cold.meta["iterations"] > 1 and not cold.meta["smoothed"]


STILL_SIZE = (640, 360)
STILL_FPS = 15.0
STILL_GRID = Grid()
STILL_SURFACE = "bowl"


def _subject(warp: Warp, salient: NDArray[np.bool_]) -> float:
    """The size inconsistency of what the display maps draw for ``warp`` on the bowl,
    over the content map's salient part (ground truth: rays cast at the surface)."""
    surface = simulate_surface(STILL_SURFACE)
    d = measure(display_float_map(warp, 4), get_surface(STILL_SURFACE), surface.projector.K)
    return d.select(in_mask(d, salient.astype(np.float32))).size_std


def test_clip_that_starts_still_is_converged_before_it_is_held() -> None:
    """A clip that starts still is refined on until its warp has converged, and only
    then held: before, the first frame's bounded solve was held for the whole still
    second, 1.47x the subject size inconsistency of a full solve of that frame.

    A face at the left on a brick texture, still for one second (15 frames at 15 fps),
    then moving right at 180 px/s, on the bowl, the device's grid and planner; the
    content maps from the real chain (saliency, the face detected and followed). The
    yardstick of a frame: an independent full solve of its own content map
    (``compute_warp``, cold, the default 10 steps), scored by ray casting over the
    map's salient part.
    """
    surface = simulate_surface(STILL_SURFACE)
    settings = WarpSettings(mode="content", grid=STILL_GRID, max_iterations=6)
    device = WarpPlanner(surface.projector, STILL_GRID, DEVICE_PLAN, WarpCache())
    cf = device.content_free(surface, STILL_SIZE, settings)
    maps = TemporalContentMap(
        STILL_SIZE,
        SaliencyModel(),
        tracker=FaceTracker(FaceDetector()),
        grid=(STILL_GRID.rows, STILL_GRID.cols),
    )
    still, moving = round(STILL_FPS), 4
    shown, ratios, steps, faces = [], [], [], []
    for i in range(still + moving):
        image, _ = face_frame(i, STILL_SIZE, still=still - 1, speed=180.0 / STILL_FPS)
        cmap = maps.update(image)
        warp = device.refine(surface, cmap, settings, cf, frame_dt=1 / STILL_FPS)
        shown.append(warp.image_xy)
        steps.append(warp.meta["iterations"])
        faces.append(len(cmap.faces))
        if i >= still - 1:  # the end of the still second, then every moving frame
            salient = cmap.full_size() >= cmap.threshold
            full = compute_warp(surface, STILL_SIZE, cmap, replace(settings, max_iterations=10))
            ratios.append(_subject(warp, salient) / _subject(full, salient))
    assert faces == [1] * (still + moving)  # the face is followed on every frame
    assert ratios[0] <= 1.3, np.round(ratios, 3)  # the end of the still second
    assert max(ratios[1:]) <= 1.5, np.round(ratios, 3)  # every moving frame
    # refined on, warm, while the picture stands still, and held once settled
    assert steps[0] > 1 and steps[1] > 0 and 0 in steps[2:still], steps
    held = steps.index(0)
    # a held picture stands still: after the fit's window has passed its last move
    xy = np.stack(shown[:still])
    move = np.linalg.norm(np.diff(xy, axis=0), axis=-1)
    settled = held + round(TemporalWarpSettings().window_s * STILL_FPS)
    assert settled < still - 1 and np.nanmax(move[settled:]) < 0.05, np.nanmax(move, axis=(1, 2))
