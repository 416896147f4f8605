"""The content-aware warp of a video, coherent in time.

A clip's content map moves with its subject (:mod:`adaproj_edge.content.temporal`), and
every frame gets a content-aware refinement
(:meth:`~adaproj_edge.warp.planner.WarpPlanner.refine` with ``frame_dt``):

- **on the full grid** (the default, :attr:`TemporalWarpSettings.full_grid`), or on
  the stills' grid (the device's for stills: coarse to fine);
- **warm-started**: the refinement starts from the previous frame's solution (the
  planner keeps it) and takes at most :attr:`TemporalWarpSettings.steps` steps, so a
  frame costs a bounded time and the solution follows the subject over a few frames;
- **graded saliency** (:class:`GradedContentMap`): a vertex's weight rises smoothly
  from 0 at ``C = T - band`` to 1 at ``C = T + band`` instead of jumping at ``T``;
- **fitted in time** (:class:`WarpSmoother`; the default): what is shown is, vertex by
  vertex, the least-squares line through the refined warps of the last
  :attr:`TemporalWarpSettings.window_s` seconds (0.4 s) against clip time, read at this
  frame's time, plus a share (``residual_gain``) of the newest refinements' mean
  residual from it; where the refinements turn (a parabola fits the window much better
  than the line: ``turn_ratio``) the line is fitted over the last ``turn_window_s``
  only. Or (``window_s`` 0) a critically damped second-order low-pass filter (two
  equal exponential stages);
- **held once converged while the content stands still**: a still content map (no
  value moved more than :attr:`TemporalWarpSettings.still_change` since the map the
  last refinement ran on) is refined on, warm-started, frame after frame, until a
  frame's refinement moves no vertex more than :attr:`TemporalWarpSettings.settle_px`
  (0.1 content px); from then on the frame takes no step and the last refined warp is
  shown again (through the filter). A frame's bounded steps (the first frame's too:
  the settings' ``max_iterations``) do not converge the alternation, so holding the
  first warp of a still scene would show an unconverged picture for as long as the
  scene stands (measured: a face still on the bowl, 1.47x the subject size
  inconsistency of a full solve of the frame, against 0.94x once converged, 4 frames
  later); and holding is what makes a still scene give a still warp.

Why: the content-aware energy of a still weighs a vertex as salient or not
(``C >= T``), so as a subject moves, vertices enter and leave the salient set one at a
time and each frame's optimum jumps - a staircase. Solved independently per frame, the
warp jerks with it (the content map, whose saliency is run every 4th frame, also moves
in a 4-frame rhythm). Graded weights make the optimum move more continuously; the
bounded warm-started steps follow it; the filter takes out what is left.

The low-pass filter (:data:`LOW_PASS`, the default before issue 15) follows a subject
moving at a steady speed with a lag (two stages of 50 ms: ~2 frames, 12 px at 180
px/s), and that lag and the coarse grid's cold first frame keep the shown warp's
subject size inconsistency up to 1.41x an independent full solve's on the test clip
(docs/video.md). The line fit follows a steady motion without lag and averages the
jitter over the window; on the full grid (:data:`LINE_FIT`) every frame of that clip
is within 1.25x, but a subject that turns back reaches 1.33x: the line overshoots the
turn for a window. The turn test and the residual's share (the defaults) bring that
clip to 1.29x and keep the others at 1.23x, the moving subject's warp still 5.1x
smoother than independent solves (the residual and a shorter window both add jitter:
a 0.3-s window alone gives 1.26x on the turn but 4.4x; measured in docs/video.md).

The smoother starts again (no blending) when the refinement starts on another
content-free warp (a new pose: the vertices then belong to another surface), when the
grid's vertex set changes, when no clip time passed since the last frame (a jump), and
after :meth:`WarpSmoother.reset`. A fitted warp that would fold a triangle is replaced
by the refined warp itself (the window starts again).

Pure: the caller passes the time between frames (seconds of clip time); no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.warp.orientation import fold_count
from adaproj_edge.warp.warpmap import Warp


@dataclass(frozen=True)
class TemporalWarpSettings:
    """How a video's warp follows its frames.

    Attributes
    ----------
    steps : int
        Content-aware steps per frame from a warm start (the first frame of a pose
        takes the settings' ``max_iterations``).
    band : float
        Half-width of the content-map interval over which a vertex's weight grows from
        0 to 1, around the threshold T (0: the still's step at T).
    time_constant_s : float
        Time constant of each of the low-pass filter's two stages (s; with
        ``window_s`` 0, as in :data:`LOW_PASS`). 0.05 s moves each stage 49 % of the
        way per frame at 30 fps (the smallest that keeps the moving subject's warp 5x
        smoother than independent solves; 0.07 s lags the subject's size).
    window_s : float
        > 0: the line fitted in time, over the refined warps of this many seconds back
        (0.4 s: 13 frames at 30 fps; see :class:`WarpSmoother`). 0: the two-stage
        low-pass filter instead.
    still_change : float
        A frame whose content map differs from the last refined one by at most this
        much everywhere takes no step once the refinement has settled (the warp is
        held; 0: always refine).
    settle_px : float
        The refinement has settled (a still content map's warp may be held) when its
        last frame, on a content map within ``still_change`` of the one before, moved
        no vertex by more than this (content pixels). Until then a still scene is
        refined on, warm-started, frame after frame.
    full_grid : bool
        Refine a clip's frames on every vertex of the warp grid, whatever the
        planner's ``refine_factor`` (False: the stills' grid, coarse to fine).
    turn_ratio : float
        With the line fit: a turn is where a parabola fits the window's refined warps
        better than the line by more than this ratio (the squared residuals the
        parabola takes off over those it leaves, all vertices together; at least
        :data:`TURN_MIN_FRAMES` frames); there the line is fitted over the last
        ``turn_window_s`` only (0: no turns). 4: the test clip's subject turning back
        (frame 22) gives 6.2-8.2 on frames 30-34, the other test clips at most 2.8.
    turn_window_s : float
        The line fit's window at a turn (s).
    residual_gain : float
        With the line fit: the share of the mean residual of the newest
        :data:`RESIDUAL_FRAMES` refined warps from the line added to what is shown
        (0: the line alone; 1: the line moved through them).
    """

    steps: int = 3
    band: float = 0.05
    time_constant_s: float = 0.05
    window_s: float = 0.4
    still_change: float = 0.01
    settle_px: float = 0.1
    full_grid: bool = True
    turn_ratio: float = 4.0
    turn_window_s: float = 0.2
    residual_gain: float = 0.2

    def __post_init__(self) -> None:
        if self.steps < 1 or not 0.0 <= self.band < 0.5 or not self.time_constant_s >= 0.0:
            raise ValueError("need steps >= 1, 0 <= band < 0.5 and time_constant_s >= 0")
        if not self.window_s >= 0.0 or not self.still_change >= 0.0:
            raise ValueError("need window_s >= 0 and still_change >= 0")
        if not self.settle_px > 0.0:
            raise ValueError("need settle_px > 0")
        if not self.turn_ratio >= 0.0 or not self.turn_window_s > 0.0:
            raise ValueError("need turn_ratio >= 0 and turn_window_s > 0")
        if not 0.0 <= self.residual_gain <= 1.0:
            raise ValueError("need 0 <= residual_gain <= 1")

    def gain(self, dt: float) -> float:
        """The fraction of the way to its input each low-pass stage moves in ``dt``
        seconds (1: no smoothing, for ``time_constant_s`` 0 or a jump in time)."""
        if self.time_constant_s <= 0.0 or not dt > 0.0:
            return 1.0
        return 1.0 - math.exp(-dt / self.time_constant_s)


TURN_MIN_FRAMES = 6
"""Frames the line fit's window needs before a turn is looked for (a parabola through
fewer follows the jitter)."""
RESIDUAL_FRAMES = 3
"""The newest refined warps whose mean residual from the line ``residual_gain`` adds."""

LINE_FIT = TemporalWarpSettings(turn_ratio=0.0, residual_gain=0.0)
"""The plain line fit on the full grid (issue 13's option): no turns, no residual (a
subject that turns back: up to 1.33x an independent full solve, docs/video.md)."""

LOW_PASS = TemporalWarpSettings(
    steps=2, band=0.1, window_s=0.0, full_grid=False, turn_ratio=0.0, residual_gain=0.0
)
"""The defaults before issue 15: the stills' (coarse) grid, 2 steps, the two-stage
low-pass filter (up to 1.41x an independent full solve, docs/video.md)."""


@dataclass(frozen=True)
class GradedContentMap(ContentMap):
    """A content map whose weights grow smoothly through the threshold.

    Attributes
    ----------
    band : float
        The weight is 0 for ``C <= T - band``, 1 for ``C >= T + band`` and a smoothstep
        in between (``band`` 0: the step of :meth:`ContentMap.weights`).
    """

    band: float = 0.1

    @classmethod
    def of(cls, content_map: ContentMap, band: float) -> GradedContentMap:
        """``content_map`` with graded weights."""
        m = content_map
        return cls(m.values, m.content_size, m.threshold, m.faces, band)

    def weights(self, xy: NDArray[np.floating]) -> NDArray[np.float32]:
        """Weights in [0, 1] at content pixel coordinates ``xy`` (n, 2)."""
        if self.band <= 0.0:
            return super().weights(xy)
        c = self.sample(xy).astype(np.float64)
        x = np.clip((c - (self.threshold - self.band)) / (2.0 * self.band), 0.0, 1.0)
        return (x * x * (3.0 - 2.0 * x)).astype(np.float32)


class WarpSmoother:
    """A filter in time on the vertices of successive warps.

    Two ways (:attr:`TemporalWarpSettings.window_s`):

    - **line fit** (``window_s`` > 0, the default): each frame's refined warp joins a
      window of the last ``window_s`` seconds; what is shown is, vertex by vertex, the
      least-squares line through the window's content coordinates against clip time,
      read at this frame's time: a steady motion is followed without lag, the jitter
      averaged over the window; where the motion changes the line overshoots (a step:
      by at most 29 %, within one window). With ``turn_ratio`` > 0, where a parabola
      fits the window that much better than the line (a turn: ``turns`` counts them),
      the line is fitted over the last ``turn_window_s`` only; with
      ``residual_gain`` > 0, that share of the newest refinements' mean residual from
      the line is added (off at a turn);
    - **low-pass** (``window_s`` 0): a critically damped second-order low-pass
      filter, two equal exponential stages of ``time_constant_s``; a step becomes an
      S-shaped move without overshoot, a steady motion is followed about
      ``2 * time_constant_s`` late.

    Parameters
    ----------
    settings : TemporalWarpSettings, optional
    """

    def __init__(self, settings: TemporalWarpSettings | None = None) -> None:
        self.settings = settings or TemporalWarpSettings()
        self._source: object | None = None
        self._times: list[float] = []  # clip time of each warp in the window (s)
        self._window: list[FloatArray] = []  # their image_xy (R, C, 2); the last only
        self._first: FloatArray | None = None  # the low-pass's first stage (R, C, 2)
        self._out: FloatArray | None = None  # and its second: what is shown
        self._refined: Warp | None = None  # the last refinement's warp
        self._refined_map: NDArray[np.float32] | None = None  # and the map it ran on
        self._refined_source: object | None = None  # and the content-free warp
        self.settled = False  # the last refinement moved no vertex more than settle_px
        self.last_move = math.inf  # its largest vertex move on a still map (content px)
        self.resets = 0
        self.holds = 0
        self.turns = 0

    def reset(self) -> None:
        """Forget the past: the next warp is shown as it comes."""
        self._source = None
        self._times, self._window = [], []
        self._first = self._out = None
        self._refined = None
        self._refined_map = None
        self._refined_source = None
        self.settled = False
        self.last_move = math.inf

    def held(self, content_map: ContentMap, source: object) -> Warp | None:
        """The last refined warp, when it has settled (:attr:`settled`), ``content_map``
        has not moved from the map it was refined on by more than ``still_change``
        anywhere and ``source`` (the content-free warp) is the same; None when this
        frame needs a refinement (a still map whose warp has not settled yet is refined
        on, warm-started).

        The returned warp's ``meta`` says ``iterations`` 0 and ``held`` True.
        """
        last = self._refined
        if last is None or not self.settled or not self._still(content_map, source):
            return None
        self.holds += 1
        return replace(last, meta={**last.meta, "iterations": 0, "held": True})

    def refined(self, warp: Warp, content_map: ContentMap, source: object) -> None:
        """Keep ``warp``, this frame's refinement of ``content_map`` from ``source``, for
        :meth:`held`; it has settled when the last refinement was of a map within
        ``still_change`` of this one and no vertex moved more than ``settle_px``."""
        last = self._refined
        still = last is not None and self._still(content_map, source)
        move = math.inf
        if still and last is not None and last.image_xy.shape == warp.image_xy.shape:
            d = np.linalg.norm(np.asarray(warp.image_xy) - np.asarray(last.image_xy), axis=-1)
            same = np.array_equal(np.isnan(d), np.isnan(np.asarray(last.image_xy)[..., 0]))
            move = float(np.nanmax(d)) if same and np.isfinite(d).any() else math.inf
        self.last_move = move
        self.settled = move <= self.settings.settle_px
        self._refined = warp
        self._refined_map = np.array(content_map.values, np.float32)
        self._refined_source = source

    def _still(self, content_map: ContentMap, source: object) -> bool:
        """Whether ``content_map`` is within ``still_change`` of the map the last
        refinement ran on, from the same ``source``."""
        values, limit = self._refined_map, self.settings.still_change
        if values is None or source is not self._refined_source or limit <= 0.0:
            return False
        now = content_map.values
        return now.shape == values.shape and float(np.max(np.abs(now - values))) <= limit

    @property
    def active(self) -> bool:
        """Whether the filter holds a past (the next warp will be fitted with it)."""
        return bool(self._window)

    def smooth(self, warp: Warp, source: object, dt: float) -> Warp:
        """The warp to show for a frame ``dt`` seconds after the last one.

        Parameters
        ----------
        warp : Warp
            This frame's refined warp; ``image_xy`` (R, C, 2), NaN where no surface.
        source : object
            What the refinement started from (the content-free warp of the pose); a
            different one starts the filter again.
        dt : float
            Seconds since the last frame (clip time; not > 0: start again).

        Returns
        -------
        Warp
            ``warp`` with its ``image_xy`` fitted in time; ``meta["smoothed"]`` says
            whether the past took part.
        """
        xy = np.asarray(warp.image_xy, np.float64)
        last = self._window[-1] if self._window else None
        fresh = (
            last is None
            or source is not self._source
            or not dt > 0.0
            or last.shape != xy.shape
            or not np.array_equal(np.isnan(last), np.isnan(xy))
        )
        if fresh:
            self._start(xy, source)
            return replace(warp, meta={**warp.meta, "smoothed": False})
        shown = self._line(xy, dt) if self.settings.window_s > 0.0 else self._lowpass(xy, dt)
        if shown is None:
            return replace(warp, meta={**warp.meta, "smoothed": False})
        smoothed = replace(warp, image_xy=shown, meta={**warp.meta, "smoothed": True})
        if fold_count(smoothed):
            self._start(xy, source)
            return replace(warp, meta={**warp.meta, "smoothed": False})
        return smoothed

    def _lowpass(self, xy: FloatArray, dt: float) -> FloatArray:
        """The two stages moved towards ``xy``; the second (what is shown)."""
        assert self._first is not None and self._out is not None  # not fresh
        g = self.settings.gain(dt)
        self._first = self._first + g * (xy - self._first)
        self._out = self._out + g * (self._first - self._out)
        self._times, self._window = [self._times[-1] + dt], [xy]
        return self._out

    def _line(self, xy: FloatArray, dt: float) -> FloatArray | None:
        """``xy`` into the window; the fitted lines at now (None: ``xy`` alone)."""
        now = self._times[-1] + dt
        keep = [i for i, t in enumerate(self._times) if t >= now - self.settings.window_s - 1e-9]
        self._times = [self._times[i] for i in keep] + [now]
        self._window = [self._window[i] for i in keep] + [xy]
        return self._fit(now) if len(self._times) >= 2 else None

    def _fit(self, now: float) -> FloatArray:
        """What is shown at time ``now``: the window's least-squares lines, vertex by
        vertex (over the last ``turn_window_s`` at a turn), moved by
        ``residual_gain`` of the newest refinements' mean residual from them."""
        s = self.settings
        times, stack = np.asarray(self._times), np.stack(self._window)
        turn = s.turn_ratio > 0.0 and times.size >= TURN_MIN_FRAMES and self._turning(times, stack)
        if turn:
            self.turns += 1
            recent = times >= now - s.turn_window_s - 1e-9
            recent[-2:] = True  # a line needs two frames, whatever the clip's rate
            times, stack = times[recent], stack[recent]
        mean_t = float(times.mean())
        t = times - mean_t
        mean = stack.mean(axis=0)
        slope = np.tensordot(t, stack - mean, axes=(0, 0)) / float(np.sum(t * t))
        out: FloatArray = mean + slope * (now - mean_t)
        if s.residual_gain > 0.0 and not turn and times.size > RESIDUAL_FRAMES + 2:
            k = RESIDUAL_FRAMES
            line = mean + slope * t[-k:, None, None, None]
            out = out + s.residual_gain * np.mean(stack[-k:] - line, axis=0)
        return out

    def _turning(self, times: FloatArray, stack: FloatArray) -> bool:
        """Whether the vertices' paths in the window turn: a parabola in time fits
        them better than a line by more than ``turn_ratio`` (module docstring)."""
        values = stack.reshape(times.size, -1)
        values = values[:, np.isfinite(values).all(axis=0)]
        t = (times - times.mean()) / max(float(np.ptp(times)), 1e-9)
        basis = np.stack([np.ones_like(t), t, t * t], axis=1)
        line = values - basis[:, :2] @ np.linalg.lstsq(basis[:, :2], values, rcond=None)[0]
        curve = values - basis @ np.linalg.lstsq(basis, values, rcond=None)[0]
        left, taken = float(np.sum(curve**2)), float(np.sum(line**2) - np.sum(curve**2))
        return taken > self.settings.turn_ratio * max(left, 1e-12)

    def _start(self, xy: FloatArray, source: object) -> None:
        self.resets += 1
        self._source = source
        self._times = [0.0]
        self._window = [xy.copy()]
        self._first = xy.copy()
        self._out = xy.copy()
