"""The device runtime: states, gestures, motion, re-estimation, faults.

States
------
``boot`` -> ``idle`` (the active content shown plainly, letterboxed) -> press ->
``capturing`` (a few depth frames averaged) -> ``projecting`` (the warped content).

Gestures (one button)
---------------------
- **press** (short, alone): capture the surface and project; while projecting, re-aim
  (capture again).
- **double press** (second press within ``double_press_s`` of the first release):
  next content item.
- **long press** (held ``long_press_s`` or more): toggle content-aware / plain (no
  pre-warp) projection.

A single press is acted on once the double-press window has passed.

While projecting
----------------
The IMU decides *moving* / *settled* with hysteresis (:mod:`adaproj_edge.motion.tracker`).
Moving: the surface is re-estimated at most every ``moving_interval_s`` and the
content-free warp follows at once (from the pose cache when the pose was seen, checked
against the current depth). Settled: estimates are averaged over time
(:class:`~adaproj_edge.geometry.depth.SurfaceFilter`), the content-aware refinement runs
once, warm-started, and after that the warp is redone only when the averaged surface
moves more than ``hysteresis_rel`` (median relative depth), so a still hand gives a
still image.

Faults
------
Depth dropouts and holes, a camera that stops sending (or raises), IMU errors, a
surface out of range, a warp that cannot be computed: the last good frame stays up
with a small status mark in the top-right corner, the reason is logged and listed in
:meth:`Runtime.status`, and the next good input clears it.

The runtime never reads a clock of its own: time is the injected clock's, so a replay
on a virtual clock makes the same decisions every time. It implements the link's
:class:`~adaproj_edge.link.device.DeviceRuntime`; content arriving from the link's
thread is queued and taken up by the runtime's own thread.
"""

from __future__ import annotations

import enum
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.app.pipeline import WarpPipeline
from adaproj_edge.app.posecache import CachedWarp, PoseCache, common_nodes, pose_key
from adaproj_edge.arrays import Image
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.errors import AdaprojError, ImageError
from adaproj_edge.fileio import read_image
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth import (
    DepthSettings,
    SurfaceEstimate,
    SurfaceFilter,
    estimate_surface,
)
from adaproj_edge.geometry.planes import PlaneSettings, snap_planes
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import Display
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.link.device import Content, Settings
from adaproj_edge.motion.tracker import MotionSettings, MotionTracker
from adaproj_edge.render.frame import RemapMaps, render_frame
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.warpmap import Grid, Warp

log = logging.getLogger(__name__)

ContentMapFn = Callable[[Image, NDArray[np.float32] | None, float], ContentMap]


class State(enum.Enum):
    BOOT = "boot"
    IDLE = "idle"
    CAPTURING = "capturing"
    PROJECTING = "projecting"


@dataclass(frozen=True)
class AppSettings:
    """Tuning of the runtime (seconds, metres, fractions)."""

    grid: Grid = field(default_factory=Grid)
    capture_frames: int = 3
    capture_timeout_s: float = 0.6
    double_press_s: float = 0.35
    long_press_s: float = 0.8
    moving_interval_s: float = 0.1
    still_interval_s: float = 0.2
    hysteresis_rel: float = 0.004
    refine_at_frames: tuple[int, ...] = (3, 6, 12)
    settle_frames: int = 3  # depth frames averaged before the refinement once settled
    depth_timeout_s: float = 0.5
    min_coverage: float = 0.3
    pose_cache_size: int = 6
    caching: bool = True
    warm_start: bool = True
    map_scale: int = 4
    refine_factor: int = 2  # the content-aware grid is this many times coarser
    refine_iterations: int = 6  # per update; the next refinement goes on from there
    keep_shown_map: bool = False  # keep the float map of the frame shown (for scoring)
    history: int = 20000  # events, updates and stage times kept (oldest dropped first)
    cache_match_rel: float = 0.01  # a cached warp serves surfaces this close (median depth)
    orientation_bin_rad: float = 0.03
    depth_bin_m: float = 0.03
    motion: MotionSettings = field(default_factory=MotionSettings)
    depth: DepthSettings = field(default_factory=DepthSettings)
    planes: PlaneSettings | None = field(default_factory=PlaneSettings)  # None: no snapping

    def grid_shape(self) -> tuple[int, int]:
        """The surface lattice: one node per warp grid vertex."""
        return self.grid.rows + 1, self.grid.cols + 1


@dataclass
class Item:
    """A content item: its image, content map (None: uniform) and settings."""

    name: str
    image: Image
    content_map: ContentMap | None
    settings: Settings = field(default_factory=Settings)

    @property
    def size(self) -> tuple[int, int]:
        return int(self.image.shape[1]), int(self.image.shape[0])


def mask_content_map(
    image: Image, mask: NDArray[np.float32] | None, threshold: float
) -> ContentMap:
    """A content map from the user mask alone (uniform without one)."""
    h, w = image.shape[:2]
    values = np.zeros((h, w), np.float32) if mask is None else mask
    return ContentMap(np.asarray(values, np.float32), (w, h), threshold)


def saliency_content_map(
    image: Image, mask: NDArray[np.float32] | None, threshold: float
) -> ContentMap:
    """Saliency (the default ONNX model) max the user mask."""
    from adaproj_edge.content.contentmap import content_map_for

    return content_map_for(image, mask, threshold=threshold)


FrameHook = Callable[[int, Image, dict[str, Any]], None]

LAST_WARP = "last-warp.npz"
MARK_COLOURS = {"camera": (0, 0, 255), "depth": (0, 160, 255), "range": (255, 0, 255)}


class Runtime:
    """The projector's runtime; feed it sensor input through the ``on_*`` methods and
    call :meth:`tick` regularly (a driver loop does both: live or replayed)."""

    def __init__(
        self,
        calibration: Calibration,
        display: Display,
        clock: Clock,
        items: list[Item],
        settings: AppSettings | None = None,
        content_map_fn: ContentMapFn = saliency_content_map,
        on_frame: FrameHook | None = None,
        state_dir: Path | None = None,
    ) -> None:
        if not items:
            raise AdaprojError("the runtime needs at least one content item")
        self.calibration = calibration
        self.display = display
        self.clock = clock
        self.settings = s = settings or AppSettings()
        self.items = list(items)
        self.current = 0
        self.content_map_fn = content_map_fn
        self.on_frame = on_frame
        self.state_dir = state_dir
        self.motion = MotionTracker(calibration.R_P_I, s.motion)
        self.pipeline = WarpPipeline(
            calibration.projector,
            s.grid,
            s.map_scale,
            s.warm_start,
            s.caching,
            s.refine_factor,
            s.history,
        )
        self.pose_cache = PoseCache(s.pose_cache_size if s.caching else 0)
        self.filter = SurfaceFilter()
        self.state = State.BOOT
        self.plain = False
        self.faults: dict[str, str] = {}
        self.errors: list[str] = []
        # the recent history, for status and replays (bounded: the device runs for days)
        self.events: deque[dict[str, Any]] = deque(maxlen=s.history)
        self.states: deque[tuple[int, str]] = deque(maxlen=s.history)
        self.updates: deque[dict[str, Any]] = deque(maxlen=s.history)
        self.latencies_ms: deque[float] = deque(maxlen=s.history)
        self.update_count = 0
        self.counters = {
            "content_free": 0,
            "content_aware": 0,
            "cache_hits": 0,
            "cache_misses": 0,
            "cache_rejected": 0,
            "estimates": 0,
            "skipped_frames": 0,
            "frames_shown": 0,
        }
        self.frame: Image = np.zeros(
            (calibration.projector.height, calibration.projector.width, 3), np.uint8
        )
        self.shown_map: NDArray[np.float32] | None = None
        self.shown_warp: Warp | None = None
        self.surface: Surface | None = None
        self._maps: RemapMaps | None = None
        self._good: Image | None = None
        self._canvas: Image | None = None
        self._cf: CachedWarp | None = None
        self._shown_depth: NDArray[np.float64] | None = None
        self._refine_pending = False
        self._settle_prepared = False
        self._shown_frames = 0
        self._captured = 0
        self._capture_ns = 0
        self._last_depth_ns: int | None = None
        self._last_estimate_ns: int | None = None
        self._press_ns: int | None = None
        self._single_ns: int | None = None
        self._motion_ns: int | None = None
        self._pending: list[Item] = []
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ helpers
    @property
    def item(self) -> Item:
        return self.items[self.current]

    def _now(self) -> int:
        return self.clock.now_ns()

    def _event(self, name: str, **detail: Any) -> None:
        self.events.append({"t_ns": self._now(), "event": name, **detail})

    def _set_state(self, state: State) -> None:
        if state != self.state or not self.states:
            self.state = state
            self.states.append((self._now(), state.value))
            log.info("state %s", state.value)

    def _fault(self, kind: str, message: str) -> None:
        if self.faults.get(kind) == message:
            return
        new = kind not in self.faults
        self.faults[kind] = message
        self.errors = [*self.errors, message][-10:]
        log.warning("%s: %s", kind, message)
        if new:
            self._event("fault", kind=kind, message=message)
            self._redraw()

    def _clear(self, *kinds: str) -> None:
        gone = [k for k in kinds if k in self.faults]
        for k in gone:
            del self.faults[k]
            log.info("%s recovered", k)
            self._event("recovered", kind=k)
        if gone:
            self._redraw()

    # ------------------------------------------------------------------ lifecycle
    def boot(self) -> None:
        """Show the active content with the last good warp (kept in ``state_dir``)
        when it fits, plainly otherwise, and wait for the button."""
        self._set_state(State.BOOT)
        warp = self._load_last_warp()
        if warp is not None:
            self.shown_warp, self.shown_map = warp, None
            self._maps = self.pipeline.maps(warp)
            self._render("boot", "last-warp")
        else:
            self._show_plain("boot")
        self._set_state(State.IDLE)

    def _load_last_warp(self) -> Warp | None:
        if self.state_dir is None or not (self.state_dir / LAST_WARP).exists():
            return None
        try:
            warp = Warp.load(self.state_dir / LAST_WARP)
        except AdaprojError as e:
            log.warning("ignoring the last warp: %s", e)
            return None
        p = self.calibration.projector
        if warp.content_size != self.item.size or (warp.projector.width, warp.projector.height) != (
            p.width,
            p.height,
        ):
            return None
        return warp

    def _save_last_warp(self, warp: Warp) -> None:
        if self.state_dir is None:
            return
        try:
            self.state_dir.mkdir(parents=True, exist_ok=True)
            warp.save(self.state_dir / LAST_WARP)
        except (OSError, AdaprojError) as e:
            log.warning("cannot keep the last warp in %s: %s", self.state_dir, e)

    # ------------------------------------------------------------------ inputs
    def on_imu(self, sample: ImuSample) -> None:
        self._clear("imu")
        change = self.motion.update(sample)
        if change is True:
            self._motion_ns = sample.receive_ns
            self._event("moving")
        elif change is False:
            self._event("settled")
            self.filter.reset()
            self._refine_pending = True
            self._settle_prepared = False

    def on_imu_error(self, message: str) -> None:
        self.motion.reset_window()
        self._fault("imu", message)

    def on_depth_error(self, message: str) -> None:
        self._fault("camera", message)

    def on_button(self, ev: ButtonEvent) -> None:
        if ev.pressed:
            self._press_ns = ev.receive_ns
            return
        if self._press_ns is None:
            return
        held = ev.receive_ns - self._press_ns
        press = self._press_ns
        self._press_ns = None
        if held >= self.settings.long_press_s * 1e9:
            self._single_ns = None
            self._gesture("long")
        elif (
            self._single_ns is not None
            and press - self._single_ns <= self.settings.double_press_s * 1e9
        ):
            self._single_ns = None
            self._gesture("double")
        else:
            self._single_ns = ev.receive_ns

    def tick(self) -> None:
        """Time-driven work: gestures that have waited out, capture and depth timeouts,
        content that came over the link."""
        now = self._now()
        self._take_pending()
        if (
            self._single_ns is not None
            and now - self._single_ns > self.settings.double_press_s * 1e9
        ):
            self._single_ns = None
            self._gesture("press")
        if (
            self.state == State.CAPTURING
            and self._captured > 0
            and now - self._capture_ns > self.settings.capture_timeout_s * 1e9
        ):
            self._finish_capture()
        if (
            self.state in (State.CAPTURING, State.PROJECTING)
            and self._last_depth_ns is not None
            and now - self._last_depth_ns > self.settings.depth_timeout_s * 1e9
            and "camera" not in self.faults
        ):
            self._fault("camera", f"no depth frame for {self.settings.depth_timeout_s:g} s")

    def on_depth(self, frame: DepthFrame) -> None:
        t_start = time.perf_counter()
        now = self._now()
        self._last_depth_ns = now
        self._clear("camera")
        if self.state not in (State.CAPTURING, State.PROJECTING):
            return
        s = self.settings
        if self.state == State.PROJECTING and self._last_estimate_ns is not None:
            # every frame while a settled refinement is on its way (it needs a few)
            interval = (
                s.moving_interval_s
                if self.motion.moving
                else 0.0
                if self._refine_pending
                else s.still_interval_s
            )
            if now - self._last_estimate_ns < interval * 1e9 - 1e6:
                self.counters["skipped_frames"] += 1
                return
        self._last_estimate_ns = now
        with self.pipeline.timer("surface"):
            try:
                est = estimate_surface(frame.metres(), self.calibration, s.grid_shape(), s.depth)
            except AdaprojError as e:
                self._fault("depth", f"depth frame unusable: {e}")
                return
        self.counters["estimates"] += 1
        if est.coverage < s.min_coverage:
            self._depth_problem(frame, est.coverage)
            return
        self._clear("depth", "range")
        moving = self.motion.moving
        if self.state == State.CAPTURING:
            self.filter.update(est, still=self._captured > 0 and not moving)
            self._captured += 1
            if self._captured >= s.capture_frames:
                self._finish_capture(t_start)
            return
        if moving:
            cur = self.filter.update(est, still=False)
            self._update(self._prepared(cur), refine=False, reason="moving", t_start=t_start)
            self._refine_pending = True
            self._settle_prepared = False
            return
        cur = self.filter.update(est, still=True)
        if self._refine_pending:
            if cur.frames < s.settle_frames:
                return  # settled: the refinement waits for a few averaged frames
            if s.caching and not self._settle_prepared and self._refines():
                # this frame makes the content-free warp of the average (into the pose
                # cache); the next one refines on it: two steps, each within a frame
                self._prepare(self._prepared(cur))
                return
        # the average gets better the longer the hand holds still: refine again a few
        # times as it does (not at every frame), otherwise only on a real change
        better = cur.frames in s.refine_at_frames and cur.frames > self._shown_frames
        if self._refine_pending or better or self._changed(cur.surface):
            reason = "settled" if self._refine_pending else "averaged" if better else "changed"
            self._update(self._prepared(cur), refine=True, reason=reason, t_start=t_start)
            self._shown_frames = cur.frames
            self._refine_pending = False

    def _prepared(self, est: SurfaceEstimate) -> Surface:
        """The surface of the (averaged) estimate, its large planar pieces snapped onto
        their planes, with the number of depth frames averaged in its ``meta``."""
        surface = replace(est.surface, meta={**est.surface.meta, "frames": est.frames})
        if self.settings.planes is None:
            return surface
        with self.pipeline.timer("planes"):
            return snap_planes(surface, self.settings.planes)[0]

    def _depth_problem(self, frame: DepthFrame, coverage: float) -> None:
        d = frame.depth_mm
        seen = float(np.mean(d > 0))
        lo, hi = self.settings.depth.min_depth_m * 1e3, self.settings.depth.max_depth_m * 1e3
        in_range = float(np.mean((d >= lo) & (d <= hi)))
        if seen > 0.3 and in_range < 0.5 * seen:
            self._fault("range", f"surface out of range ({lo / 1e3:g}-{hi / 1e3:g} m)")
        else:
            self._fault(
                "depth", f"depth dropout: surface seen on {100 * coverage:.0f} % of the frame"
            )

    def _changed(self, surface: Surface) -> bool:
        if self._shown_depth is None:
            return True
        pair = common_nodes(surface.points[..., 2].astype(np.float64), self._shown_depth)
        if pair is None:
            return True
        z, shown = pair
        both = np.isfinite(z) & np.isfinite(shown)
        if both.sum() < 0.9 * np.isfinite(z).sum():
            return True
        rel = np.abs(z[both] - shown[both]) / shown[both]
        return bool(np.median(rel) > self.settings.hysteresis_rel)

    # ------------------------------------------------------------------ gestures
    def _gesture(self, kind: str) -> None:
        self._event("gesture", kind=kind)
        if kind == "press":
            self._start_capture()
        elif kind == "double":
            self.current = (self.current + 1) % len(self.items)
            self._event("content", item=self.item.name)
            self._reshow("next item")
        elif kind == "long":
            self.plain = not self.plain
            self._event("mode", plain=self.plain)
            self._reshow("mode")

    def _start_capture(self) -> None:
        self.filter.reset()
        self._captured = 0
        self._capture_ns = self._now()
        self._set_state(State.CAPTURING)

    def _finish_capture(self, t_start: float | None = None) -> None:
        cur = self.filter.current
        if cur is None:
            return
        self._set_state(State.PROJECTING)
        self._refine_pending = self.motion.moving
        self._settle_prepared = False
        self._update(self._prepared(cur), refine=True, reason="capture", t_start=t_start)
        self._shown_frames = cur.frames

    def _reshow(self, reason: str) -> None:
        if self.state == State.PROJECTING and self.surface is not None:
            self._update(self.surface, refine=True, reason=reason)
        else:
            self._show_plain(reason)

    # ------------------------------------------------------------------ warps
    def _warp_settings(self) -> WarpSettings:
        st = self.item.settings
        return WarpSettings(
            mode="content",
            grid=self.settings.grid,
            threshold=st.threshold,
            max_iterations=self.settings.refine_iterations,
        )

    def _refines(self) -> bool:
        """Whether updates of the current item run the content-aware refinement."""
        item = self.item
        return not self.plain and item.settings.mode == "content" and item.content_map is not None

    def _prepare(self, surface: Surface) -> None:
        """The content-free warp of ``surface`` into the pose cache (nothing shown)."""
        self._settle_prepared = True
        with self.pipeline.timer("prepare"):
            try:
                self._content_free(surface, refine=True)
            except AdaprojError as e:
                self._fault("warp", f"no warp for this surface: {e}")

    def _content_free(self, surface: Surface, refine: bool) -> tuple[CachedWarp, bool]:
        """The content-free warp of ``surface``: from the pose cache when the pose was
        seen (for a refinement: from a surface averaged about as long), else solved and
        cached. Returns it and whether it was a cache hit."""
        item = self.item
        depth = surface.points[..., 2].astype(np.float64)
        key = (
            pose_key(
                self.motion.orientation_vector(),
                depth,
                self.settings.orientation_bin_rad,
                self.settings.depth_bin_m,
            )
            + item.size
        )
        t_lookup = time.perf_counter()
        # a refinement builds only on a warp from an averaged surface, never on a
        # single-frame one from while the hand moved (2-4x the distortion)
        frames = int(surface.meta.get("frames", 1)) if refine else 0
        min_frames = min(frames, self.settings.settle_frames)
        cf = (
            self.pose_cache.get(key, depth, self.settings.cache_match_rel, min_frames=min_frames)
            if self.settings.caching
            else None
        )
        hit = cf is not None
        self.pipeline.times.add(
            "cache_hit" if hit else "cache_lookup", time.perf_counter() - t_lookup
        )
        if cf is not None:
            self.counters["cache_hits"] += 1
        else:
            self.counters["cache_misses"] += 1
            cf = self.pipeline.content_free(surface, item.size, self._warp_settings())
            self.counters["content_free"] += 1
            self.pose_cache.put(key, cf)
        self.counters["cache_rejected"] = self.pose_cache.rejected
        return cf, hit

    def _update(
        self, surface: Surface, refine: bool, reason: str, t_start: float | None = None
    ) -> None:
        t_update = time.perf_counter()
        t0 = t_start if t_start is not None else t_update
        item = self.item
        if self.plain or item.settings.mode == "standard":
            self.surface = surface
            self._show_plain(reason)
            return
        settings = self._warp_settings()
        depth = surface.points[..., 2].astype(np.float64)
        try:
            cf, hit = self._content_free(surface, refine)
            if refine and item.content_map is not None and item.settings.mode == "content":
                warp, maps = self.pipeline.content_aware(surface, item.content_map, settings, cf)
                kind, its = "content-aware", int(warp.meta["iterations"])
                self.counters["content_aware"] += 1
            else:
                warp, kind, its = cf.warp, "content-free", 0
                maps = self.pipeline.content_free_maps(cf)
        except AdaprojError as e:
            self._fault("warp", f"no warp for this surface: {e}")
            return
        self._clear("warp")
        self.surface = surface
        self._cf = cf
        self._shown_depth = depth
        self.shown_warp, self._maps = warp, maps
        frame = self._render(reason, kind, notify=False)
        t_end = time.perf_counter()
        elapsed = t_end - t0
        # the update itself (surface -> frame shown), and with the depth frame's surface
        # estimate before it (depth frame -> frame shown)
        self.pipeline.times.add("update_" + kind, t_end - t_update)
        if t_start is not None:
            self.pipeline.times.add("depth_to_frame_" + kind, elapsed)
        # after the update is timed: what only replays and the state directory need
        if frame is not None:
            self._notify(frame, reason, kind)
        self.shown_map = (
            self.pipeline.display_map(warp)
            if self.settings.keep_shown_map and kind == "content-aware"
            else None
        )
        if refine:
            self._save_last_warp(warp)
        if self._motion_ns is not None:
            self.latencies_ms.append((self._now() - self._motion_ns) / 1e6 + elapsed * 1e3)
            self._motion_ns = None
        self.update_count += 1
        self.updates.append(
            {
                "t_ns": self._now(),
                "reason": reason,
                "kind": kind,
                "cache_hit": hit,
                "iterations": its,
                "probes": _probes(warp),
                "update_ms": round((t_end - t_update) * 1e3, 3),  # wall clock: not a decision
            }
        )

    def _show_plain(self, reason: str) -> None:
        warp, maps = self.pipeline.plain(self.item.size)
        self.shown_warp, self._maps, self.shown_map = warp, maps, None
        self._shown_depth = None
        self._render(reason, "plain")

    # ------------------------------------------------------------------ display
    def _render(self, reason: str, kind: str, notify: bool = True) -> Image | None:
        """Draw the current maps and show the frame; returns the frame shown. Without
        ``notify`` the frame hook is left to the caller (:meth:`_notify`)."""
        if self._maps is None:
            return None
        with self.pipeline.timer("render"):
            frame = render_frame(self.item.image, self._maps, self._canvas)
            self._canvas = frame  # drawn into again next time
            if frame.ndim == 2:
                frame = np.asarray(cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR), np.uint8)
        self._good = frame
        with self.pipeline.timer("show"):
            out = self._show(frame)
        if notify:
            self._notify(out, reason, kind)
        return out

    def _redraw(self) -> None:
        good = self._good
        if good is not None:
            self._notify(self._show(good), "status", "status")

    def _show(self, frame: Image) -> Image:
        out = draw_status(frame, sorted(self.faults))
        self.display.show(out)
        self.frame = out
        self.counters["frames_shown"] += 1
        return out

    def _notify(self, frame: Image, reason: str, kind: str) -> None:
        """Hand the frame shown to the frame hook (replays record it)."""
        if self.on_frame is not None:
            info = {"reason": reason, "kind": kind, "faults": sorted(self.faults)}
            self.on_frame(self._now(), frame, info)

    # ------------------------------------------------------------------ link side
    def activate(self, content: Content) -> None:
        """Called from the link's thread: read and check the content, queue it."""
        try:
            image = read_image(content.image)
            mask = None
            if content.mask is not None:
                m = read_image(content.mask, gray=True)
                if m.shape[:2] != image.shape[:2]:
                    raise ImageError(
                        f"mask {content.mask.name} is {m.shape[1]}x{m.shape[0]}, "
                        f"image {content.image.name} is {image.shape[1]}x{image.shape[0]}"
                    )
                mask = (m.astype(np.float32) / 255.0).astype(np.float32)
            cmap = self.content_map_fn(image, mask, content.settings.threshold)
        except AdaprojError as e:
            self.errors = [*self.errors, str(e)][-10:]
            raise
        item = Item(content.image.name, image, cmap, content.settings)
        with self._lock:
            self._pending.append(item)

    def _take_pending(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, []
        for item in pending:
            names = [i.name for i in self.items]
            if item.name in names:
                self.items[names.index(item.name)] = item
                self.current = names.index(item.name)
            else:
                self.items.append(item)
                self.current = len(self.items) - 1
            self._event("content", item=item.name, source="link")
            self._reshow("new content")

    def status(self) -> dict[str, Any]:
        w = self.shown_warp
        return {
            "state": self.state.value,
            "image": self.item.name,
            "plain": self.plain,
            "settings": self.item.settings.to_dict(),
            "frame": [self.calibration.projector.width, self.calibration.projector.height],
            "coverage": None if self.surface is None else round(self.surface.valid_fraction, 4),
            "warp": None
            if w is None
            else {"mode": w.meta.get("mode"), "iterations": w.meta.get("iterations", 0)},
            "faults": dict(self.faults),
            "errors": self.errors[-5:],
            "counters": dict(self.counters),
        }

    def frame_png(self) -> bytes:
        ok, enc = cv2.imencode(".png", self.frame)
        if not ok:
            raise ImageError("cannot encode the current frame as PNG")
        return bytes(enc.tobytes())


def draw_status(frame: Image, faults: list[str]) -> Image:
    """``frame`` with a small square per fault in the top-right corner (none: as is)."""
    if not faults:
        return frame
    out = frame.copy()
    w = out.shape[1]
    for i, kind in enumerate(faults):
        x1 = w - 8 - i * 20
        colour = MARK_COLOURS.get(kind, (0, 255, 255))
        cv2.rectangle(out, (x1 - 12, 8), (x1, 20), colour, thickness=-1)
    return out


def _probes(warp: Warp) -> list[list[float] | None]:
    """``image_xy`` at five vertices (corners and centre), rounded; None where unknown."""
    r, c = warp.image_xy.shape[:2]
    out: list[list[float] | None] = []
    for i, j in ((0, 0), (0, c - 1), (r // 2, c // 2), (r - 1, 0), (r - 1, c - 1)):
        v = warp.image_xy[i, j]
        out.append(
            None if not np.isfinite(v).all() else [round(float(v[0]), 2), round(float(v[1]), 2)]
        )
    return out
