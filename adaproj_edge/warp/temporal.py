"""The content-aware warp of a video, coherent in time.

A clip's content map moves with its subject (:mod:`adaproj_edge.content.temporal`), and
every frame gets a content-aware refinement
(:meth:`~adaproj_edge.warp.planner.WarpPlanner.refine` with ``frame_dt``):

- **warm-started**: the refinement starts from the previous frame's solution (the
  planner keeps it) and takes at most :attr:`TemporalWarpSettings.steps` steps, so a
  frame costs a bounded time and the solution follows the subject over a few frames;
- **graded saliency** (:class:`GradedContentMap`): a vertex's weight rises smoothly
  from 0 at ``C = T - band`` to 1 at ``C = T + band`` instead of jumping at ``T``;
- **filtered in time** (:class:`WarpSmoother`): what is shown is the refined warp
  through a critically damped second-order low-pass filter (two equal exponential
  stages) on the content coordinates of the grid's vertices;
- **held while the content stands still**: when no value of the content map has moved
  more than :attr:`TemporalWarpSettings.still_change` since the map the last
  refinement ran on, the frame takes no step and the last refined warp is shown again
  (through the filter). The alternation from a warm start does not stand still on an
  unchanged map (measured: its vertices wander 1-13 content px per frame), so without
  the hold a still scene would never give a still warp.

Why: the content-aware energy of a still weighs a vertex as salient or not
(``C >= T``), so as a subject moves, vertices enter and leave the salient set one at a
time and each frame's optimum jumps - a staircase. Solved independently per frame, the
warp jerks with it. Graded weights make the optimum move continuously with the
(smoothly moving) content map; the bounded warm-started steps follow it; the filter
takes out what is left (a step becomes an S-shaped move without overshoot). A subject
moving at a steady speed is followed with a lag of about ``2 * time_constant_s``
(70 ms by default); a still scene settles to a warp that does not move at all (the
refinement is held, the filter converges geometrically to the held warp).

The smoother starts again (no blending) when the refinement starts on another
content-free warp (a new pose: the vertices then belong to another surface), when the
grid's vertex set changes, and after :meth:`WarpSmoother.reset`. A filtered warp that
would fold a triangle (never seen: both inputs are fold-free and close) is replaced by
the refined warp itself.

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
        Time constant of each of the filter's two stages (s). 0.05 s moves each stage
        49 % of the way per frame at 30 fps (the smallest that keeps the moving
        subject's warp 5x smoother than independent solves since those became
        steadier with the guarded alternation; 0.07 s lags the subject's size).
    still_change : float
        A frame whose content map differs from the last refined one by at most this
        much everywhere takes no step (the warp is held; 0: always refine).
    """

    steps: int = 2
    band: float = 0.1
    time_constant_s: float = 0.05
    still_change: float = 0.01

    def __post_init__(self) -> None:
        if self.steps < 1 or not 0.0 <= self.band < 0.5 or not self.time_constant_s >= 0.0:
            raise ValueError("need steps >= 1, 0 <= band < 0.5 and time_constant_s >= 0")
        if not self.still_change >= 0.0:
            raise ValueError("need still_change >= 0")

    def gain(self, dt: float) -> float:
        """The fraction of the way to its input each stage moves in ``dt`` seconds
        (1: no smoothing, for ``time_constant_s`` 0 or a jump in time)."""
        if self.time_constant_s <= 0.0 or not dt > 0.0:
            return 1.0
        return 1.0 - math.exp(-dt / self.time_constant_s)


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
    """A critically damped low-pass filter on the vertices of successive warps.

    Parameters
    ----------
    settings : TemporalWarpSettings, optional
    """

    def __init__(self, settings: TemporalWarpSettings | None = None) -> None:
        self.settings = settings or TemporalWarpSettings()
        self._source: object | None = None
        self._first: FloatArray | None = None  # the first stage's state (R, C, 2)
        self._out: FloatArray | None = None  # the second stage's: what is shown
        self._refined: Warp | None = None  # the last refinement's warp
        self._refined_map: NDArray[np.float32] | None = None  # and the map it ran on
        self.resets = 0
        self.holds = 0

    def reset(self) -> None:
        """Forget the past: the next warp is shown as it comes."""
        self._source = None
        self._first = None
        self._out = None
        self._refined = None
        self._refined_map = None

    def held(self, content_map: ContentMap, source: object) -> Warp | None:
        """The last refined warp, when ``content_map`` has not moved from the map it
        was refined on by more than ``still_change`` anywhere and ``source`` (the
        content-free warp) is the same; None when this frame needs a refinement.

        The returned warp's ``meta`` says ``iterations`` 0 and ``held`` True.
        """
        last, values = self._refined, self._refined_map
        limit = self.settings.still_change
        if last is None or values is None or source is not self._source or limit <= 0.0:
            return None
        now = content_map.values
        if now.shape != values.shape or float(np.max(np.abs(now - values))) > limit:
            return None
        self.holds += 1
        return replace(last, meta={**last.meta, "iterations": 0, "held": True})

    def refined(self, warp: Warp, content_map: ContentMap) -> None:
        """Keep ``warp``, this frame's refinement of ``content_map``, for :meth:`held`."""
        self._refined = warp
        self._refined_map = np.array(content_map.values, np.float32)

    @property
    def active(self) -> bool:
        """Whether the filter holds a past (the next warp will be blended into it)."""
        return self._out is not None

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
            Seconds since the last frame (clip time).

        Returns
        -------
        Warp
            ``warp`` with its ``image_xy`` filtered in time; ``meta["smoothed"]`` says
            whether it was blended with the past.
        """
        xy = np.asarray(warp.image_xy, np.float64)
        out, first = self._out, self._first
        fresh = (
            out is None
            or first is None
            or source is not self._source
            or out.shape != xy.shape
            or not np.array_equal(np.isnan(out), np.isnan(xy))
        )
        if fresh or out is None or first is None:
            self._start(xy, source)
            return replace(warp, meta={**warp.meta, "smoothed": False})
        g = self.settings.gain(dt)
        first = first + g * (xy - first)
        shown = out + g * (first - out)
        smoothed = replace(warp, image_xy=shown, meta={**warp.meta, "smoothed": True})
        if fold_count(smoothed):
            self._start(xy, source)
            return replace(warp, meta={**warp.meta, "smoothed": False})
        self._first, self._out = first, shown
        return smoothed

    def _start(self, xy: FloatArray, source: object) -> None:
        self.resets += 1
        self._source = source
        self._first = xy.copy()
        self._out = xy.copy()
