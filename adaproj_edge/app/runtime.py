"""The device runtime: states, gestures, motion, re-estimation, faults.

States
------
``boot`` -> ``idle`` (the active content shown plainly, letterboxed) -> press ->
``capturing`` (a few depth frames averaged) -> ``projecting`` (the warped content).

Gestures (one button, :mod:`adaproj_edge.app.gestures`)
--------------------------------------------------------
- **press**: capture the surface and project; while projecting, re-aim.
- **double press**: next content item.
- **long press**: toggle content-aware / plain (no pre-warp) projection.
- **tap-hold** (a short press, then a second one held like a long press): pause or
  resume the clip being played.
- **hold** (``calibrate_hold_s``, 5 s): calibrate. The runtime only raises
  :attr:`Runtime.calibration_wanted`; the device loop (:mod:`adaproj_edge.app.live`)
  hands the devices to the calibration procedure and gives the result back through
  :meth:`Runtime.recalibrate`. A replay has no devices to hand over: the request is
  logged as an event and dropped.
- **tap, then hold** (a short press, then a second one held 5 s): measure the
  surface's colour again (:attr:`Runtime.colour_wanted`; the device loop shows black,
  white and the primaries, measures and gives the result back through
  :meth:`Runtime.remeasured`; a replay drops the request as it does the hold's).

While projecting
----------------
The IMU decides *moving* / *settled* with hysteresis
(:class:`~adaproj_edge.motion.tracker.MotionTracker`). Moving: the surface is
re-estimated at most every ``moving_interval_s`` and the content-free warp follows at
once (from the pose cache when the pose was seen). Settled: estimates are averaged
over time; once ``settle_frames`` are in, one frame makes the content-free warp of the
average (into the pose cache, nothing shown) and the next runs the content-aware
refinement on it; after that the warp is redone only when the average has improved
(``refine_at_frames``) or the surface moved more than ``hysteresis_rel``, so a still
hand gives a still image.

Clips
-----
When the active item is a clip, every tick shows the frame due at the clip's own rate
(:class:`~adaproj_edge.app.playback.Playback`: looped, paused and resumed, a frame that
does not decode keeps the last good one up): while projecting content-aware, refined
per frame from the pose's content-free warp (the planner's ``frame_dt`` path); in the
other states through the maps shown. Surface updates draw the clip's current frame
with its current content map.

Faults
------
A surface the warp asked for cannot be made on goes down the warp chain
(:mod:`~adaproj_edge.warp.fallback`: content-free, repaired, the dominant plane's
keystone); each step down is logged with its reason and counted (``fallback_<step>``).
Depth dropouts and holes, a camera that stops sending (or raises), IMU errors, a
surface out of range, a warp that cannot be computed at all: the last good frame stays up
with a small status mark (:mod:`adaproj_edge.app.status`), the reason is logged and
listed in :meth:`Runtime.status`, and the next good input clears it.

The data path of one depth frame: :class:`~adaproj_edge.app.surfaces.SurfaceSource`
(estimate, average, snap walls) -> :class:`~adaproj_edge.app.warps.WarpSource` (the
warp planner, the pose cache, the display-map builder; "up" is gravity, from the
accelerometer and the gyro) -> ``render_frame`` -> the display loop
(:class:`~adaproj_edge.app.display_loop.DisplayLoop`), which shows the last frame at
every refresh of the projector, stabilised with the gyro. The runtime never reads a
clock of its own for decisions: time is the injected clock's, so a replay on a
virtual clock makes the same decisions every time (stage times are measured and only
reported). It implements the link's
:class:`~adaproj_edge.link.device.DeviceRuntime`; content arriving from the link's
thread is queued and taken up by the runtime's own thread.

This file is about 650 lines on purpose: the runtime's decisions (states, when to
estimate, when to refine, what to show, which clip frame) stay in one class so the
policy reads in one place; everything those decisions use lives in a module of its own
(``gestures``, ``surfaces``, ``warps``, ``output``, ``status``, ``telemetry``,
``content``, ``playback``, ``laststate``).
"""

from __future__ import annotations

import enum
import logging
from pathlib import Path
from typing import Any

import numpy as np

from adaproj_edge.app.content import (
    ClipMapsFn,
    ContentMapFn,
    Inbox,
    Item,
    SaliencyMaps,
    clip_maps_of,
    load_item,
)
from adaproj_edge.app.display_loop import DisplayLoop
from adaproj_edge.app.gestures import Gesture, Gestures
from adaproj_edge.app.laststate import LastWarp
from adaproj_edge.app.output import FrameHook, Output
from adaproj_edge.app.playback import Playback
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.status import Faults
from adaproj_edge.app.surfaces import SurfaceSource
from adaproj_edge.app.telemetry import Telemetry, probes
from adaproj_edge.app.warps import PoseEntry, WarpSource
from adaproj_edge.arrays import Float32Array, FloatArray, Image
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.estimate import SurfaceEstimate
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import Display
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.link.device import Content
from adaproj_edge.motion.tracker import MotionTracker
from adaproj_edge.motion.upright import Upright, UprightSettings
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.fallback import chain_of
from adaproj_edge.warp.placement import DEFAULT_UP
from adaproj_edge.warp.warpmap import Warp

log = logging.getLogger(__name__)


class State(enum.Enum):
    """The runtime's states."""

    BOOT = "boot"
    IDLE = "idle"
    CAPTURING = "capturing"
    PROJECTING = "projecting"


class Runtime:
    """The projector's runtime; feed it sensor input (:mod:`adaproj_edge.app.inputs`)
    and call :meth:`tick` regularly (a driver loop does both: live or replayed)."""

    def __init__(
        self,
        calibration: Calibration,
        display: Display,
        clock: Clock,
        items: list[Item],
        settings: AppSettings | None = None,
        content_map_fn: ContentMapFn | None = None,
        on_frame: FrameHook | None = None,
        state_dir: Path | None = None,
        clip_maps: ClipMapsFn | None = None,
    ) -> None:
        if not items:
            raise AdaprojError("the runtime needs at least one content item")
        self.calibration = calibration
        self.display = display
        self.clock = clock
        self.settings = s = settings or AppSettings()
        self.items = list(items)
        self.current = 0
        self.content_map_fn: ContentMapFn = content_map_fn or SaliencyMaps()
        self.clip_maps = clip_maps or clip_maps_of(self.content_map_fn)
        self.playback: Playback | None = None  # the active item's, when it is a clip
        self.last_warp = LastWarp(state_dir)
        self.telemetry = t = Telemetry(s.history)
        self.motion = MotionTracker(calibration.R_P_I, s.motion)
        self.upright = Upright(UprightSettings(gravity=s.gravity))
        self.gestures = Gestures(s.double_press_s, s.long_press_s, s.calibrate_hold_s)
        self.surfaces = SurfaceSource(calibration, s, t.times)
        self.warps = WarpSource(
            calibration.projector, s, t, calibration.vignetting, self.surfaces.estimator.sensor
        )
        self.faults = Faults()
        self.state = State.BOOT
        self.plain = False
        p = calibration.projector
        self.screen = DisplayLoop(display, p, calibration.R_P_I, s.display, t)
        self.imu_direct = False  # True: the IMU's reader feeds self.screen itself (live)
        self.output = Output(self.screen, clock, self.faults, t, (p.width, p.height), on_frame)
        self.shown_map: Float32Array | None = None  # kept for scoring (keep_shown_map)
        self.surface: Surface | None = None  # the surface shown, and its frames averaged
        self._surface_frames = 1
        self._shown_depth: FloatArray | None = None
        self._refine_pending = False
        self._settle_prepared = False
        self._shown_kind = "plain"  # what the last surface update showed
        self._entry: PoseEntry | None = None  # and the pose it showed
        self._logged_down: list[tuple[str, str]] = []  # the warp chain's last steps down
        self._shown_frames = 0
        self._captured = 0
        self._capture_ns = 0
        self._last_depth_ns: int | None = None
        self._last_estimate_ns: int | None = None
        self._motion_ns: int | None = None
        self.inbox = Inbox()
        self.calibration_wanted = False  # the hold gesture asks the device loop for it
        self.colour_wanted = False  # the tap-then-hold gesture asks the device loop for it

    # ------------------------------------------------------------------ helpers
    @property
    def item(self) -> Item:
        """The content item shown."""
        return self.items[self.current]

    @property
    def shown_warp(self) -> Warp | None:
        """The warp of the frame shown."""
        return self.output.warp

    @property
    def frame(self) -> Image:
        """The frame shown now."""
        return self.output.frame

    @property
    def counters(self) -> dict[str, int]:
        """The runtime's counters (warps, cache, estimates, frames)."""
        return self.telemetry.counters

    def _now(self) -> int:
        return self.clock.now_ns()

    def _event(self, name: str, **detail: Any) -> None:
        self.telemetry.event(self._now(), name, **detail)

    def _set_state(self, state: State) -> None:
        if state != self.state or not self.telemetry.states:
            self.state = state
            self.telemetry.states.append((self._now(), state.value))
            log.info("state %s", state.value)

    def _fault(self, kind: str, message: str) -> None:
        new = self.faults.set(kind, message)
        if new:
            self._event("fault", kind=kind, message=message)
            self.output.redraw()

    def _clear(self, *kinds: str) -> None:
        gone = self.faults.clear(*kinds)
        for k in gone:
            self._event("recovered", kind=k)
        if gone:
            self.output.redraw()

    # ------------------------------------------------------------------ lifecycle
    def boot(self) -> None:
        """Show the active content with the last good warp (kept in ``state_dir``)
        when it fits, plainly otherwise, and wait for the button."""
        self._set_state(State.BOOT)
        self._play_item()
        warp = self.last_warp.load(self.calibration.projector, self.item.size)
        if warp is not None:
            self.shown_map = None
            self.output.content = self.item.name
            self.output.set(warp, self.warps.maps(warp))
            self.output.render(self._image(), "boot", "last-warp")
            self._shown_kind, self._entry = "last-warp", None
        else:
            self._show_plain("boot")
        self._set_state(State.IDLE)

    # ------------------------------------------------------------------ inputs
    def on_imu(self, sample: ImuSample) -> None:
        """One IMU sample: motion state, orientation, gravity, and (unless the IMU's
        reader feeds it directly) the display loop's stabiliser."""
        self._clear("imu")
        if not self.imu_direct:
            self.screen.on_imu(sample)
        change = self.motion.update(sample)
        R = self.calibration.R_P_I
        accel = R @ (np.asarray(sample.accel, dtype=np.float64) - self.calibration.accel_offset)
        rate = R @ np.asarray(sample.gyro, dtype=np.float64)
        # gravity decides by itself when the accelerometer can be used (the tracker's
        # "moving" also counts a tremor too strong for the depth average); it integrates
        # the rate with its offset (a drift it fits), the learnt offset only tells turns
        bias = self.motion.bias
        self.upright.update(sample.sensor_ns, accel, rate, True, R @ bias.value, bias.learnt_s)
        if change is True:
            self._motion_ns = sample.receive_ns
            self._event("moving")
        elif change is False:
            self._event("settled")
            self.surfaces.filter.reset()
            self._refine_pending = True
            self._settle_prepared = False

    def on_source_fault(self, source: str, message: str) -> None:
        """A device that failed to deliver (``source``: "depth", "imu", "button")."""
        if source == "imu":
            self.motion.reset_window()
            self.screen.imu_fault()
            self._fault("imu", message)
        elif source == "depth":
            self._fault("camera", message)
        else:
            log.error("%s: %s", source, message)

    def on_button(self, ev: ButtonEvent) -> None:
        """One button event (press or release)."""
        gesture = self.gestures.on_button(ev)
        if gesture is not None:
            self._gesture(gesture)

    def tick(self) -> None:
        """Time-driven work: gestures that have waited out, capture and depth timeouts,
        content that came over the link."""
        now = self._now()
        self._take_pending()
        gesture = self.gestures.tick(now)
        if gesture is not None:
            self._gesture(gesture)
        self._play_clip(now)
        s = self.settings
        if (
            self.state == State.CAPTURING
            and self._captured > 0
            and now - self._capture_ns > s.capture_timeout_s * 1e9
        ):
            self._finish_capture()
        if (
            self.state in (State.CAPTURING, State.PROJECTING)
            and self._last_depth_ns is not None
            and now - self._last_depth_ns > s.depth_timeout_s * 1e9
            and "camera" not in self.faults
        ):
            self._fault("camera", f"no depth frame for {s.depth_timeout_s:g} s")

    def on_depth(self, frame: DepthFrame) -> None:
        """One depth frame: estimate the surface when it is time, and update the warp
        as the state and the motion call for."""
        t_start = self.telemetry.times.now()
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
                self.telemetry.count("skipped_frames")
                return
        self._last_estimate_ns = now
        try:
            est = self.surfaces.estimate(frame)
        except AdaprojError as e:
            self._fault("depth", f"depth frame unusable: {e}")
            return
        self.telemetry.count("estimates")
        if est.seen_coverage < s.min_coverage or est.coverage == 0.0:
            self._fault(*self.surfaces.depth_problem(frame, est.seen_coverage))
            return
        self._clear("depth", "range")
        filt = self.surfaces.filter
        moving = self.motion.moving
        if self.state == State.CAPTURING:
            filt.update(est, still=self._captured > 0 and not moving)
            self._captured += 1
            if self._captured >= s.capture_frames:
                self._finish_capture(t_start)
            return
        if moving:
            cur = filt.update(est, still=False)
            self._update(cur, refine=False, reason="moving", t_start=t_start)
            self._refine_pending = True
            self._settle_prepared = False
            return
        cur = filt.update(est, still=True)
        if self._refine_pending:
            if cur.frames < s.settle_frames:
                return  # settled: the refinement waits for a few averaged frames
            if s.caching and not self._settle_prepared and self._refines():
                # this frame makes the content-free warp of the average (into the pose
                # cache); the next one refines on it: two steps, each within a frame
                self._prepare(cur)
                return
        # the average gets better the longer the hand holds still: refine again a few
        # times as it does (not at every frame), otherwise only on a real change
        better = cur.frames in s.refine_at_frames and cur.frames > self._shown_frames
        changed = self.surfaces.changed(cur.surface, self._shown_depth)
        if self._refine_pending or better or changed:
            reason = "settled" if self._refine_pending else "averaged" if better else "changed"
            self._update(cur, refine=True, reason=reason, t_start=t_start)
            self._shown_frames = cur.frames
            self._refine_pending = False

    # ------------------------------------------------------------------ gestures
    def _gesture(self, kind: Gesture) -> None:
        self._event("gesture", kind=kind)
        if kind == "press":
            self._start_capture()
        elif kind == "double":
            self.current = (self.current + 1) % len(self.items)
            self._event("content", item=self.item.name)
            self._play_item()
            self._reshow("next item")
        elif kind == "long":
            self.plain = not self.plain
            self._event("mode", plain=self.plain)
            self._reshow("mode")
        elif kind == "tap_hold":
            if self.playback is not None:
                paused = self.playback.toggle(self._now())
                self._event("clip", item=self.item.name, paused=paused)
        elif kind == "hold":
            self.calibration_wanted = True
        elif kind == "colour":
            self.colour_wanted = True

    def remeasured(self, measured: Measured | None, reason: str) -> None:
        """Go on after the colour captures: with ``measured`` (a new measurement of the
        surface's colour; ``None`` keeps the one in use, or the geometric gain alone),
        from idle, the content shown plainly (the captures took the projector)."""
        self.colour_wanted = False
        if measured is not None:
            s, t, cal = self.settings, self.telemetry, self.calibration
            sensor = self.surfaces.estimator.sensor
            self.warps = WarpSource(cal.projector, s, t, cal.vignetting, sensor)  # no stale gains
            self.warps.measured = measured
        self._event("colour_measured", changed=measured is not None, reason=reason)
        self._set_state(State.IDLE)
        self._show_plain("colour measured")

    def recalibrate(self, calibration: Calibration | None, reason: str) -> None:
        """Go on after a calibration run: with ``calibration`` (a new one was written;
        ``None`` keeps the one in use), from idle, the content shown plainly.

        Raises
        ------
        AdaprojError
            ``calibration`` describes another projector size than the display's (the
            runtime keeps the calibration in use).
        """
        self.calibration_wanted = False
        if calibration is not None:
            old, new = self.calibration.projector, calibration.projector
            if (new.width, new.height) != (old.width, old.height):
                raise AdaprojError(
                    f"the new calibration is for a {new.width}x{new.height} projector, "
                    f"the display is {old.width}x{old.height}; the old one stays in use"
                )
            s, t = self.settings, self.telemetry
            self.calibration = calibration
            self.motion = MotionTracker(calibration.R_P_I, s.motion)
            self.upright = Upright(UprightSettings(gravity=s.gravity))
            self.screen.recalibrate(calibration.projector, calibration.R_P_I)
            self.surfaces = SurfaceSource(calibration, s, t.times)
            # the surface's colour measured before stays (its holds_on judges each surface)
            measured = self.warps.measured
            sensor = self.surfaces.estimator.sensor
            self.warps = WarpSource(calibration.projector, s, t, calibration.vignetting, sensor)
            self.warps.measured = measured
            self.surface = None
        self._event("calibrated", changed=calibration is not None, reason=reason)
        self._set_state(State.IDLE)
        self._show_plain("calibration")

    def _start_capture(self) -> None:
        self.surfaces.filter.reset()
        self._captured = 0
        self._capture_ns = self._now()
        self._set_state(State.CAPTURING)

    def _finish_capture(self, t_start: float | None = None) -> None:
        cur = self.surfaces.filter.current
        if cur is None:
            return
        self._set_state(State.PROJECTING)
        self._refine_pending = self.motion.moving
        self._settle_prepared = False
        self._update(cur, refine=True, reason="capture", t_start=t_start)
        self._shown_frames = cur.frames

    def _reshow(self, reason: str) -> None:
        if self.state == State.PROJECTING and self.surface is not None:
            self._show_warp(self.surface, self._surface_frames, True, reason, None)
        else:
            self._show_plain(reason)

    # ------------------------------------------------------------------ warps
    def up(self) -> tuple[float, float, float]:
        """The warps' "up" in frame P: gravity's estimate followed with a dead band and
        a rate limit (:class:`~adaproj_edge.motion.upright.Upright`), once it is trusted
        (the projector's -y before)."""
        g = self.upright.up
        if g is None:
            return DEFAULT_UP
        return (float(g[0]), float(g[1]), float(g[2]))

    def _warp_settings(self) -> WarpSettings:
        return WarpSettings(
            mode="content",
            grid=self.settings.grid,
            threshold=self.item.settings.threshold,
            max_iterations=self.settings.refine_iterations,
            up=self.up(),
        )

    def _refines(self) -> bool:
        """Whether updates of the current item run the content-aware refinement."""
        item = self.item
        return not self.plain and item.settings.mode == "content" and item.content_map is not None

    def _prepare(self, est: SurfaceEstimate) -> None:
        """The content-free warp of the averaged ``est`` into the pose cache, and what
        its first refinement measures of it alone (:meth:`PoseEntry.prepare`, timed as
        ``refine_prep``; nothing shown)."""
        self._settle_prepared = True
        surface = self.surfaces.prepared(est)
        with self.telemetry.times.timer("prepare"):
            try:
                entry, _ = self._pose(surface, est.frames, refine=True)
            except AdaprojError as e:
                self._fault("warp", f"no warp for this surface: {e}")
                return
            cmap = self._content_map()
            if cmap is not None and not self.plain and self.item.settings.mode == "content":
                with self.telemetry.times.timer("refine_prep"):
                    try:
                        entry.prepare(cmap, self.up())
                    except AdaprojError as e:  # made ahead only: the refinement meets it
                        log.info("nothing made ahead for the refinement: %s", e)

    def _pose(self, surface: Surface, frames: int, refine: bool) -> tuple[PoseEntry, bool]:
        """The pose entry of ``surface`` (averaged over ``frames`` depth frames) and
        whether it was a cache hit. A refinement builds only on a content-free warp from
        a surface averaged about as long, never on a single-frame one from while the
        hand moved (2-4x the distortion)."""
        min_frames = min(frames, self.settings.settle_frames) if refine else 0
        orientation = self.motion.orientation_vector()
        return self.warps.pose(
            surface, frames, min_frames, orientation, self.item.size, self._warp_settings()
        )

    def _update(
        self, est: SurfaceEstimate, refine: bool, reason: str, t_start: float | None = None
    ) -> None:
        """Show the warp of the (averaged) estimate ``est``, its walls snapped."""
        self._show_warp(self.surfaces.prepared(est), est.frames, refine, reason, t_start)

    def _show_warp(
        self, surface: Surface, frames: int, refine: bool, reason: str, t_start: float | None
    ) -> None:
        t_update = self.telemetry.times.now()
        t0 = t_start if t_start is not None else t_update
        item = self.item
        if self.plain or item.settings.mode == "standard":
            self.surface, self._surface_frames = surface, frames
            self._show_plain(reason)
            return
        aware = refine and item.content_map is not None and item.settings.mode == "content"
        kind = "content-aware" if aware else "content-free"
        try:
            entry, hit = self._pose(surface, frames, refine)
            cmap = self._content_map()
            if aware and cmap is not None:
                settings = self._warp_settings()
                warp, maps = self.warps.content_aware(surface, cmap, settings, entry)
                self.telemetry.count("content_aware")
            else:
                warp, maps = entry.warp, self.warps.content_free_maps(entry)
        except AdaprojError as e:  # the chain's last step: the last good picture stays
            self.telemetry.count("fallback_last-good")
            self._fault("warp", f"no warp for this surface: {e}")
            return
        step = self._stepped_down(warp, reason)
        self._clear("warp")
        self.surface, self._surface_frames = surface, frames
        self._shown_depth = surface.points[..., 2].astype(np.float64)
        self.output.content = item.name
        gain = self.warps.gain(entry, surface, frames)
        self.output.set(warp, maps, gain, frames)
        self._shown_kind, self._entry = kind, entry
        frame = self.output.render(self._image(), reason, kind, notify=False)
        t_end = self.telemetry.times.now()
        elapsed = t_end - t0
        # the update itself (surface -> frame shown), and with the depth frame's surface
        # estimate before it (depth frame -> frame shown)
        times = self.telemetry.times
        times.add("update_" + kind, t_end - t_update)
        if t_start is not None:
            times.add("depth_to_frame_" + kind, elapsed)
        # after the update is timed: what only replays and the state directory need
        if frame is not None:
            self.output.notify(frame, reason, kind)
        keep = self.settings.keep_shown_map and kind == "content-aware"
        self.shown_map = self.warps.float_map(warp) if keep else None
        if refine:
            self.last_warp.save(warp)
        if self._motion_ns is not None:
            latency = (self._now() - self._motion_ns) / 1e6 + elapsed * 1e3
            self.telemetry.latencies_ms.append(latency)
            self._motion_ns = None
        self.telemetry.update(
            self._now(),
            reason=reason,
            kind=kind,
            cache_hit=hit,
            iterations=int(warp.meta.get("iterations", 0)) if aware else 0,
            probes=probes(warp),
            step=step,
            update_ms=round((t_end - t_update) * 1e3, 3),  # wall clock: not a decision
            **({} if gain is None else {"photometry": gain.summary()}),
        )

    def _stepped_down(self, warp: Warp, reason: str) -> str:
        """The step of the chain ``warp`` ended at (:mod:`~adaproj_edge.warp.fallback`);
        each step it went down from is logged with its reason, and the step counted
        (``fallback_<step>``)."""
        step, down = chain_of(warp)
        if down:
            self.telemetry.count("fallback_" + step)
            if down != self._logged_down:  # the same again (a pose cached): logged once
                for gone, why in down:
                    log.warning("%s update: no %s warp (%s); showing %s", reason, gone, why, step)
        self._logged_down = down
        return step

    def _show_plain(self, reason: str) -> None:
        self.output.content = self.item.name
        self.output.set(*self.warps.plain(self.item.size))
        self.shown_map = None
        self._shown_depth = None
        self._shown_kind, self._entry = "plain", None
        self.output.render(self._image(), reason, "plain")

    # ------------------------------------------------------------------ clips
    def _image(self) -> Image:
        """The active item's picture now: a clip's current frame."""
        pb = self.playback
        return pb.current.image if pb is not None and pb.current is not None else self.item.image

    def _content_map(self) -> ContentMap | None:
        """The active item's content map now: a clip's current frame's."""
        pb = self.playback
        if pb is not None and pb.current is not None:
            return pb.current.content_map
        return self.item.content_map

    def _play_item(self) -> None:
        """Start playing the active item when it is a clip (stop the one played)."""
        if self.playback is not None:
            self.playback.close()
            self.playback = None
        item = self.item
        if item.clip is None:
            return
        try:
            self.playback = Playback.open(
                item.clip,
                self.clip_maps(item),
                item.name,
                self._now(),
                self.telemetry,
                self.faults.note_error,
            )
        except AdaprojError as e:  # its first frame is shown as a still
            self._event("clip_error", item=item.name, message=str(e))
            self.faults.note_error(f"{item.name}: {e}")
            log.warning("%s: cannot play: %s", item.name, e)
            return
        self.warps.planner.forget()  # another content: no warm start from the last
        self._event("clip", item=item.name, paused=False)

    def _play_clip(self, now: int) -> None:
        """Show the clip's frame due ``now`` (one at most)."""
        pb = self.playback
        if pb is None or not pb.due(now):
            return
        step = pb.advance(now)
        if step is None:
            return  # did not decode: the last good frame stays up
        kind = self._shown_kind
        if kind == "content-aware" and self._entry is not None and self.surface is not None:
            try:
                warp, maps = self.warps.content_aware(
                    self.surface, step.content_map, self._warp_settings(), self._entry, step.dt
                )
            except AdaprojError as e:
                self.telemetry.count("fallback_last-good")
                self._fault("warp", f"no warp for this clip frame: {e}")
                return
            self._stepped_down(warp, "clip")
            gain = self.warps.gain(self._entry, self.surface)
            self.output.set(warp, maps, gain, self._surface_frames)
        self.output.render(step.image, "clip", kind)
        pb.shown(self._now())

    # ------------------------------------------------------------------ link side
    def activate(self, content: Content) -> None:
        """Called from the link's thread: read and check the content, queue it."""
        try:
            self.inbox.put(load_item(content, self.content_map_fn))
        except AdaprojError as e:
            self.faults.note_error(str(e))
            raise

    def _take_pending(self) -> None:
        for item in self.inbox.take():
            names = [i.name for i in self.items]
            if item.name in names:
                self.items[names.index(item.name)] = item
                self.current = names.index(item.name)
            else:
                self.items.append(item)
                self.current = len(self.items) - 1
            self._event("content", item=item.name, source="link")
            self._play_item()
            self._reshow("new content")

    def status(self) -> dict[str, Any]:
        """The device's status for the link (state, content, warp, faults, counters)."""
        w = self.shown_warp
        p = self.calibration.projector
        return {
            "state": self.state.value,
            "image": self.item.name,
            "plain": self.plain,
            "settings": self.item.settings.to_dict(),
            "frame": [p.width, p.height],
            "coverage": None if self.surface is None else round(self.surface.valid_fraction, 4),
            "warp": None
            if w is None
            else {"mode": w.meta.get("mode"), "iterations": w.meta.get("iterations", 0)},
            "faults": dict(self.faults.active),
            "errors": self.faults.errors[-5:],
            "counters": dict(self.counters),
            "clip": None if self.playback is None else self.playback.status(self._now()),
        }

    def frame_png(self) -> bytes:
        """The frame shown now, as PNG bytes."""
        return self.output.png()
