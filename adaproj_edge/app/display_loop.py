"""The display loop: at every refresh of the projector, the last rendered frame moved
for the device's rotation, stabilised, predicted to when it is lit.

The runtime renders a frame when a depth frame calls for it (10-15 times a second at
most) and hands it here (:meth:`DisplayLoop.publish`); the IMU's samples come here as
they are read (:meth:`DisplayLoop.on_imu`). Each refresh, ``lead_s`` before the
vertical sync, :meth:`DisplayLoop.prepare` steps the stabiliser to the moment the
frame will be lit (the middle of the refresh period that follows the sync), draws the
frame through the homography of its correction (:mod:`adaproj_edge.render.reproject`)
and marks the active faults on it; at the sync it is handed to the display
(:meth:`DisplayLoop.show_prepared`). Without a stabilisation margin the frame is shown
as rendered (the runtime before the display loop).

A new frame of the same content places it a little differently from the last one (a
refinement redistributes it, a new surface estimate or "up" moves it by a few
millimetres): shown as it comes, that is a jump. Instead the new frame starts where the
old one's content was on the display (the homography that best carries the new placement
of a grid of content points onto the old one: a change of shape as well as a shift) and
glides to its own placement with time constant ``glide_s`` (the homography eased towards
the identity; ``glide_moving_s`` for a frame published while the device is turned on
purpose). A larger change (over ``max_glide`` of the margin: other content, a frame that
follows a deliberate turn) is shown at once, except where it is the same surface
measured again: while the device is not turned on purpose (the stabiliser's ``turning``:
the deliberate rate over ``moving_rate`` now and in its mean over a quarter of a
second; a strong tremor lifts the rate of the moment alone over it while the hand holds
still), or when a frame
made from a surface averaged over more depth frames replaces one from fewer (the
hand-over after a move), it glides from as far as ``max_handover_glide`` of the frame's
size (judged at the content points, not at the frame's corners: a re-placement on a
corner is no homography, and the fit's corners can sit twice as far off as the content).
Single-frame surfaces miss nodes where the depth had holes, and their placement can sit
a tenth of the frame away from the averaged one's (or the next single frame's), a fifth
smaller: shown at once, that is a jump of centimetres while the hand holds still (after
each move; and on and on while a strong tremor keeps the motion tracker's "moving" on).

Threads (on the device, :func:`run_display`): the display thread owns the display and
the frame being prepared; the runtime's thread renders and publishes; the IMU reader's
thread feeds the stabiliser directly (the runtime's queue would hold samples back
while a depth frame is processed). Two locks: one for the stabiliser, one for the
published frame (publishing converts into a spare buffer and swaps it in). In a replay
everything runs on one thread, refreshes on the virtual clock between records
(:mod:`adaproj_edge.app.replay`), with the compute time measured and the wait for the
sync modelled: a frame whose computation took longer than ``lead_s`` is handed one or
more refreshes later. The computation counted is the step's CPU time
(``time.thread_time``): what it costs on a core of its own, as the display thread has
on the device, not how long other programs sharing the machine kept it waiting (its
wall-clock time is reported beside it, stage ``refresh``).

Before the loop runs (:attr:`DisplayLoop.running`), a published frame is shown at once,
as it always was.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from adaproj_edge.app.settings import DisplaySettings
from adaproj_edge.app.status import draw_status, mark_faults
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.display import Display
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.motion.stabiliser import Stabiliser
from adaproj_edge.render.content_points import content_points, frame_pixels
from adaproj_edge.render.reproject import (
    inner_corners,
    inset_warp,
    map_points,
    reproject,
    rotation_homography,
)
from adaproj_edge.warp.warpmap import Warp

WARPED = ("content-free", "content-aware")
"""Kinds of frame that show warped content."""

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Shown:
    """What a published frame shows: its number, its kind ("plain", "content-free",
    "content-aware", ...), its warp (before the margin's inset), the content's name and
    the depth frames averaged into the surface its warp was made for (0: none)."""

    frame_id: int
    kind: str
    warp: Warp | None
    content: str = ""
    frames: int = 0


@dataclass(frozen=True)
class Refresh:
    """One refresh.

    Attributes
    ----------
    vsync_ns : int
        The refresh the frame was computed for.
    handed_ns : int
        When it was handed to the display (a missed refresh: a later one).
    lit_ns : int
        The moment the correction was predicted to (the middle of the lit period).
    sample_ns : int or None
        Sensor time of the newest IMU sample the correction used.
    C : (3, 3) float array
        The stabiliser's correction (a rotation; identity when stabilisation is off).
    glide : (3, 3) float array
        The glide between rendered frames (a homography from the corrected display's
        pixels to the rendered frame's): the frame is drawn with
        ``glide @ K C K^-1``.
    usage : float
        Share of the margin the correction used.
    compute_s : float
        Measured CPU time of the stabiliser step, the reprojection and the marks.
    shown : Shown or None
        The frame shown (None before any).
    """

    vsync_ns: int
    handed_ns: int
    lit_ns: int
    sample_ns: int | None
    C: FloatArray
    glide: FloatArray
    usage: float
    compute_s: float
    shown: Shown | None

    @property
    def latency_ms(self) -> float | None:
        """IMU sample -> frame handed to the display (ms); None without a sample."""
        if self.sample_ns is None:
            return None
        return (self.handed_ns - self.sample_ns) / 1e6


RefreshHook = Callable[[Refresh], None]


class DisplayLoop:
    """What the projector shows, refresh by refresh.

    Parameters
    ----------
    display : Display
    projector : Projector
        Intrinsics and size of the frame.
    R_P_I : (3, 3) float array
        IMU frame -> projector frame.
    settings : DisplaySettings
    telemetry : Telemetry
        Stage times ("stabilise", "reproject", "refresh"), the refresh counters and the
        motion-to-photon latencies.
    on_refresh : RefreshHook, optional
        Called with every refresh (replays score them).
    """

    def __init__(
        self,
        display: Display,
        projector: Projector,
        R_P_I: FloatArray,
        settings: DisplaySettings,
        telemetry: Telemetry,
        on_refresh: RefreshHook | None = None,
    ) -> None:
        self.display = display
        self.settings = settings
        self.telemetry = telemetry
        self.on_refresh = on_refresh
        self.R_P_I = np.asarray(R_P_I, dtype=np.float64)
        self.K = projector.K
        self.period_ns = round(1e9 / settings.refresh_hz)
        self.stabiliser = Stabiliser(
            projector.K, (projector.width, projector.height), settings.stabiliser
        )
        shape = (projector.height, projector.width, 4)
        self._buffers = [np.zeros(shape, np.uint8), np.zeros(shape, np.uint8)]
        self._current = 0
        self._out = np.zeros(shape, np.uint8)
        self._marks: list[str] = []
        self._shown: Shown | None = None
        self._pixels_memo: tuple[Warp, float, FloatArray] | None = None
        self._glide = np.eye(3)  # the glide's homography when published
        self._glide_ns = 0
        self._glide_tau_s = settings.glide_s  # its time constant
        self._imu_lock = threading.Lock()
        self._frame_lock = threading.Lock()
        self.running = False
        self.last: Refresh | None = None

    def recalibrate(self, projector: Projector, R_P_I: FloatArray) -> None:
        """Go on with a new calibration of the same projector size (the gyro track
        starts again: its rates were turned into frame P by the old ``R_P_I``)."""
        with self._imu_lock, self._frame_lock:
            self.R_P_I = np.asarray(R_P_I, dtype=np.float64)
            self.K = projector.K
            self.stabiliser = Stabiliser(
                projector.K, (projector.width, projector.height), self.settings.stabiliser
            )

    @property
    def stabilising(self) -> bool:
        """Whether refreshes correct the frame (a stabilisation margin is set)."""
        return self.settings.stabiliser.enabled

    # ------------------------------------------------------------------ inputs
    def on_imu(self, sample: ImuSample) -> None:
        """One IMU sample (any thread)."""
        rate = self.R_P_I @ np.asarray(sample.gyro, dtype=np.float64)
        with self._imu_lock:
            self.stabiliser.add_gyro(sample.sensor_ns, rate)

    def imu_fault(self) -> None:
        """The IMU failed: no correction until its samples come again."""
        with self._imu_lock:
            self.stabiliser.reset()

    def publish(self, frame: Image, marks: list[str], shown: Shown, t_ns: int) -> None:
        """A newly rendered frame (H, W, 3) BGR, without marks, the faults to mark on it,
        what it shows and when it was published (the runtime's thread)."""
        spare = 1 - self._current
        cv2.cvtColor(frame, cv2.COLOR_BGR2BGRA, dst=self._buffers[spare])
        glide = self._glide_to(shown, t_ns)
        tau = self._glide_tau()
        with self._frame_lock:
            self._current = spare
            self._marks = list(marks)
            self._shown = shown
            self._glide, self._glide_ns, self._glide_tau_s = glide, t_ns, tau
        if not self.running:
            self.display.show(draw_status(frame, marks))

    def _glide_at(self, t_ns: int) -> FloatArray:
        """The glide's homography (3, 3) at ``t_ns``: from a pixel of the corrected
        display to the rendered frame's."""
        age = max(0, t_ns - self._glide_ns) * 1e-9
        a = math.exp(-age / self._glide_tau_s) if self._glide_tau_s > 0 else 0.0
        out: FloatArray = np.eye(3) + a * (self._glide - np.eye(3))
        return out

    def _glide_tau(self) -> float:
        """The glide's time constant for a frame published now: ``glide_s`` held still,
        towards ``glide_moving_s`` as the device is turned on purpose (the stabiliser's
        deliberate rate, blended as its follower's time constant is). Turned, frames
        come every ``moving_interval_s``: a slow glide would never finish, and each new
        frame would start from the last one's lag (the content's tilt and place behind
        the device's by a glide's worth after the turn)."""
        s = self.settings
        with self._imu_lock:
            v = self.stabiliser.deliberate_rate / self.settings.stabiliser.moving_rate
        return s.glide_moving_s + (s.glide_s - s.glide_moving_s) / (1.0 + v * v)

    def _glide_to(self, new: Shown, t_ns: int) -> FloatArray:
        """The glide (homography, 3 x 3) that starts ``new`` where the frame shown now
        puts its content; the identity when there is nothing to glide from."""
        old = self._shown
        s = self.settings
        if (
            not self.stabilising
            or s.glide_s <= 0
            or old is None
            or old.warp is None
            or new.warp is None
            or old.kind not in WARPED
            or new.kind not in WARPED
            or old.content != new.content
            or old.warp.content_size != new.warp.content_size
        ):
            return np.eye(3)
        margin = s.stabiliser.margin
        u_old = self._content_pixels(old.warp, margin)
        u_new = self._content_pixels(new.warp, margin)
        with self._frame_lock:
            G_old = self._glide_at(t_ns)
        u_old = map_points(np.asarray(np.linalg.inv(G_old), dtype=np.float64), u_old)
        ok = np.isfinite(u_new).all(axis=1) & np.isfinite(u_old).all(axis=1)
        if ok.sum() < 4:
            return np.eye(3)
        found, _ = cv2.findHomography(u_new[ok], u_old[ok], 0)
        if found is None or not np.all(np.isfinite(found)):
            return np.eye(3)
        A = np.asarray(found, dtype=np.float64)
        w, h = self.stabiliser.size
        # the change is judged against the old frame's own placement, not where its
        # glide has it now: a small change during a glide carries the glide on
        G = G_old @ A
        with self._imu_lock:
            # turned on purpose, not only trembling: a strong tremor lifts the
            # deliberate rate itself over moving_rate while the hand holds still
            held = not self.stabiliser.turning
        if held or new.frames > old.frames > 0:  # the same surface, measured again
            # judged where the content is: a re-placement across a corner's crease is
            # no homography, and the fit's frame corners can sit twice as far off
            d = np.abs(map_points(G, u_new[ok]) - u_new[ok])
            if max(d[:, 0].max() / w, d[:, 1].max() / h) > s.max_handover_glide:
                return np.eye(3)
        else:
            corners = inner_corners((w, h), margin)
            d = np.abs(map_points(G, corners) - corners)
            if max(d[:, 0].max() / (margin * w), d[:, 1].max() / (margin * h)) > s.max_glide:
                return np.eye(3)
        out: FloatArray = np.asarray(np.linalg.inv(A), dtype=np.float64)
        out /= out[2, 2]
        return out

    def _content_pixels(self, warp: Warp, margin: float) -> FloatArray:
        """Where ``warp`` (inset by ``margin``) shows the content points
        (:func:`~adaproj_edge.render.content_points.frame_pixels`); the last warp's are
        kept, so a glide finds the frame shown now's without inverting its mesh again."""
        memo = self._pixels_memo
        if memo is not None and memo[0] is warp and memo[1] == margin:
            return memo[2]
        uv = frame_pixels(inset_warp(warp, margin), content_points(warp.content_size))
        self._pixels_memo = (warp, margin, uv)
        return uv

    # ------------------------------------------------------------------ refreshes
    def prepare(self, vsync_ns: int) -> Refresh:
        """Compute the frame for the refresh at ``vsync_ns`` (call ``lead_s`` before it);
        :meth:`show_prepared` hands it over. The record's ``handed_ns`` is ``vsync_ns``
        (the caller knows better: :meth:`refresh`, :func:`run_display`)."""
        self.running = True
        cpu0 = time.thread_time()
        t0 = time.perf_counter()
        times = self.telemetry.times
        lit_ns = vsync_ns + self.period_ns // 2
        with self._imu_lock:
            correction = self.stabiliser.step(lit_ns)
            sample_ns = self.stabiliser.track.last_ns
        t1 = time.perf_counter()
        C = correction.C
        with self._frame_lock:
            src = self._buffers[self._current]
            glide = self._glide_at(lit_ns) if self.stabilising else np.eye(3)
            if self.stabilising:
                H = glide @ rotation_homography(self.K, C)
                reproject(src, H, self._out, self.settings.interpolation)
            else:
                np.copyto(self._out, src)
            mark_faults(self._out, self._marks)
            shown = self._shown
        t2 = time.perf_counter()
        cpu = time.thread_time() - cpu0
        times.add("stabilise", t1 - t0)
        times.add("reproject", t2 - t1)
        times.add("refresh", t2 - t0)
        times.add("refresh_cpu", cpu)
        return Refresh(
            vsync_ns, vsync_ns, lit_ns, sample_ns, C, glide, correction.usage, cpu, shown
        )

    def show_prepared(self) -> None:
        """Hand the prepared frame to the display."""
        with self.telemetry.times.timer("display_copy"):
            self.display.show(self._out)

    def record(self, refresh: Refresh) -> None:
        """Count a refresh handed to the display, its latency, and pass it on."""
        t = self.telemetry
        t.count("refreshes")
        if refresh.handed_ns > refresh.vsync_ns:
            t.count("refresh_misses")
        latency = refresh.latency_ms
        if latency is not None and self.stabilising:
            t.photon_ms.append(latency)
        self.last = refresh
        if self.on_refresh is not None:
            self.on_refresh(refresh)

    def refresh(self, vsync_ns: int) -> Refresh:
        """One refresh on a virtual clock (replays): prepare, hand over, record. The
        computation is timed; the frame is handed at ``vsync_ns`` if it took at most
        ``lead_s``, else at the first refresh after it finished (modelled)."""
        r = self.prepare(vsync_ns)
        late_ns = round(r.compute_s * 1e9) - round(self.settings.lead_s * 1e9)
        if late_ns > 0:
            missed = -(-late_ns // self.period_ns)
            r = _handed(r, vsync_ns + missed * self.period_ns)
        self.show_prepared()
        self.record(r)
        return r


def _handed(r: Refresh, handed_ns: int) -> Refresh:
    return replace(r, handed_ns=handed_ns)


def run_display(loop: DisplayLoop, clock: Clock, stop: threading.Event) -> None:
    """The device's display thread: wait for each refresh, hand over the frame prepared
    for it, sleep until ``lead_s`` before the next one and prepare that one. A display
    that fails is logged and tried again a second later."""
    lead_ns = round(loop.settings.lead_s * 1e9)
    prepared: Refresh | None = None
    while not stop.is_set():
        try:
            vsync = loop.display.wait_refresh()
            if prepared is not None:
                loop.show_prepared()
                loop.record(_handed(prepared, clock.now_ns()))
            clock.sleep_until(vsync + loop.period_ns - lead_ns)
            prepared = loop.prepare(vsync + loop.period_ns)
        except AdaprojError as e:
            log.error("display: %s", e)
            prepared = None
            clock.sleep_until(clock.now_ns() + 1_000_000_000)


def refresh_summary(telemetry: Telemetry) -> dict[str, Any]:
    """Refreshes, missed refreshes and the motion-to-photon latency (ms, median and
    95th percentile) of a run."""
    lat = np.asarray(telemetry.photon_ms)
    return {
        "refreshes": telemetry.counters["refreshes"],
        "missed": telemetry.counters["refresh_misses"],
        "motion_to_photon_ms": {
            "n": int(lat.size),
            "median": round(float(np.median(lat)), 2) if lat.size else None,
            "p95": round(float(np.percentile(lat, 95)), 2) if lat.size else None,
        },
    }
