"""Where the runtime's warps and display maps come from: one warp planner
(:class:`~adaproj_edge.warp.planner.WarpPlanner`, coarse-to-fine and warm-started), one
display-map builder (:class:`~adaproj_edge.render.display_maps.DisplayMapBuilder`) and
the pose cache between them.

A pose's entry holds its content-free warp, the pixel weights of its mesh (every warp of
that pose maps through them) and, once shown, the content-free warp's own maps. Lookups
key on the IMU orientation, a depth signature and "up" (gravity), and every candidate
is checked node by node against the current surface (within what the depth sensor's
noise makes of one surface: :func:`~adaproj_edge.warp.posecache.surfaces_agree`), for
the same "up" (within
``up_match_rad``; :mod:`adaproj_edge.warp.posecache`) and for the content's size. An
entry of the same surface made for another "up", while the device turned at most
``orientation_bin_rad``, is placed upright again instead of solved anew (its solves
depend on the surface alone: :meth:`~adaproj_edge.warp.planner.WarpPlanner.with_up`,
timed as ``re_place``, counted as ``re_placed``).

Every map drawn for the display has the content inset by the stabilisation margin
(:func:`~adaproj_edge.render.reproject.inset_warp`): the warps themselves (cached,
warm-started, saved, probed) are the planner's.

With ``settings.photometry`` set, a pose's entry also keeps the brightness gain made
from its surface (:mod:`adaproj_edge.render.photometry`, made when first shown): a
cached pose's frames cost one multiply more, nothing else. With the surface's colour
measured (:attr:`WarpSource.measured`) and the device still before that surface, the
gain is the measured colour gain instead (:mod:`adaproj_edge.render.reflectance`);
off that surface, the geometric one, and the reason is logged.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.arrays import Float32Array, FloatArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.irradiance import Vignetting
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.render.display_maps import DisplayMapBuilder
from adaproj_edge.render.frame import RemapMaps
from adaproj_edge.render.maps import PixelWeights
from adaproj_edge.render.photometry import GainMap, gain_map
from adaproj_edge.render.reflectance import colour_gain, plan
from adaproj_edge.render.reproject import inset_warp
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.planner import ContentFreeWarp, PlanSettings, WarpPlanner
from adaproj_edge.warp.posecache import PoseCache, pose_key, surface_turn, surfaces_agree
from adaproj_edge.warp.warpmap import Warp

log = logging.getLogger(__name__)


@dataclass
class PoseEntry:
    """What the device keeps per pose.

    Attributes
    ----------
    content_free : ContentFreeWarp
        The content-free warp and the solver's positions (warm starts).
    weights : PixelWeights
        The reduced-resolution pixel weights of its mesh.
    frames : int
        Depth frames averaged into the surface it was made from.
    up : (3,) float array
        The "up" (frame P) its content was placed upright with.
    orientation : (3,) float array
        The device's orientation (rotation vector) when it was made.
    maps : RemapMaps or None
        The content-free warp's own display maps, made when first shown.
    gain : GainMap or None
        The brightness gain of its surface, made when first shown (with photometry on).
    gain_frames : int
        Depth frames averaged into the surface the gain was made from.
    """

    content_free: ContentFreeWarp
    weights: PixelWeights
    frames: int
    up: FloatArray
    orientation: FloatArray
    maps: RemapMaps | None = None
    gain: GainMap | None = None
    gain_frames: int = 0

    def prepare(self, content_map: ContentMap, up: FloatArray | tuple[float, ...]) -> None:
        """Make ahead what the first content-aware refinement of this entry with
        ``content_map`` and ``up`` measures of its content-free warp alone
        (:meth:`~adaproj_edge.warp.planner.ContentFreeWarp.prepare`; kept on it, made
        again for an entry re-placed for another "up")."""
        self.content_free.prepare(content_map, up)

    @property
    def depth(self) -> FloatArray:
        """The lattice depth (R, C) of the surface this entry was made for."""
        return self.content_free.depth

    @property
    def warp(self) -> Warp:
        """The content-free warp."""
        return self.content_free.warp


class WarpSource:
    """The runtime's warps and maps.

    Parameters
    ----------
    projector : Projector
    settings : AppSettings
        The grid (the content-free solve's; the refinement's is coarser), map scale,
        refinement factor, warm starts, caching and the pose cache's tuning.
    telemetry : Telemetry
        Where the stage times and cache counters go.
    vignetting : Vignetting, optional
        The projector lens's falloff (the calibration's), for the brightness gain.
    sensor : SensorModel, optional
        The depth sensor's noise model (the calibration's depth camera, of the kind
        ``settings.depth.sensor``), what the pose cache judges a surface's difference
        against; default: a nominal OAK-D's of that kind.
    """

    def __init__(
        self,
        projector: Projector,
        settings: AppSettings,
        telemetry: Telemetry,
        vignetting: Vignetting | None = None,
        sensor: SensorModel | None = None,
    ) -> None:
        s = self.settings = settings
        self.projector = projector
        self.sensor = sensor or SensorModel.of(DepthCameraModel.oak_d(), s.depth.sensor)
        self.vignetting = vignetting
        self.telemetry = telemetry
        self.times = telemetry.times
        self.caching = s.caching
        plan = PlanSettings(refine_factor=s.refine_factor, warm_start=s.warm_start)
        cache = WarpCache() if s.caching else None
        self.planner = WarpPlanner(projector, s.grid, plan, cache)
        self.display = DisplayMapBuilder(projector, s.grid.vertices(projector), s.map_scale)
        self.poses: PoseCache[PoseEntry] = PoseCache(s.pose_cache_size if s.caching else 0)
        self.margin = s.display.stabiliser.margin
        self.measured: Measured | None = None
        """The surface's colour measured by ``adaproj calibrate --photometric`` (used by
        :meth:`gain` while the device stays on that surface)."""
        self._colour: GainMap | str | None = None
        self._said = ""

    def shown(self, warp: Warp) -> Warp:
        """``warp`` as drawn: its content inset by the stabilisation margin."""
        return inset_warp(warp, self.margin)

    def maps(self, warp: Warp) -> RemapMaps:
        """The renderer's maps for any warp (one loaded at boot, say)."""
        with self.times.timer("map"):
            return self.display.maps(self.shown(warp))

    def plain(self, content_size: tuple[int, int]) -> tuple[Warp, RemapMaps]:
        """The content letterboxed on the frame (no pre-warp), and its maps."""
        warp = self.planner.standard(content_size)
        return warp, self.maps(warp)

    def pose(
        self,
        surface: Surface,
        frames: int,
        min_frames: int,
        orientation: FloatArray,
        content_size: tuple[int, int],
        settings: WarpSettings,
    ) -> tuple[PoseEntry, bool]:
        """The pose entry of ``surface`` (averaged over ``frames`` depth frames): from
        the cache when the pose was seen (made from at least ``min_frames`` frames),
        else solved and cached; and whether it was a cache hit.

        Parameters
        ----------
        surface : Surface
        frames, min_frames : int
        orientation : (3,) float array
            The device's orientation (rotation vector), part of the key.
        content_size : (w, h)
        settings : WarpSettings
        """
        s = self.settings
        depth = surface.points[..., 2].astype(np.float64)
        up = np.asarray(settings.up, dtype=np.float64)
        key = pose_key(orientation, depth, s.orientation_bin_rad, s.depth_bin_m, up, s.up_bin_rad)
        key += content_size
        t_lookup = self.telemetry.times.now()

        def unturned(e: PoseEntry) -> bool:
            # depths within the noise let the surface turn in P by a degree or two (the
            # device turned before a wall turned away): its warp would tip the content
            return surface_turn(surface.points, e.depth) <= s.cache_turn_rad

        def same(now: FloatArray, e: PoseEntry) -> bool:
            # the surface's difference judged against the sensor's noise at its depth,
            # averaged over the frames each estimate holds
            return surfaces_agree(
                now,
                e.depth,
                (frames, e.frames),
                self.sensor,
                s.cache_match_sigmas,
                s.cache_spread_sigmas,
                s.cache_overlap,
                s.cache_sway_m,
            )

        def fits(e: PoseEntry) -> bool:
            # the same "up", and made for content of this size: an entry found by its
            # surface alone may be another item's (its content coordinates another scale)
            same_up = float(np.linalg.norm(e.up - up)) <= s.up_match_rad
            return same_up and e.warp.content_size == content_size and unturned(e)

        entry = (
            self.poses.get(key, depth, min_frames=min_frames, accept=fits, match=same)
            if self.caching
            else None
        )
        self.telemetry.times.add(
            "cache_hit" if entry is not None else "cache_lookup",
            self.telemetry.times.now() - t_lookup,
        )
        hit = entry is not None
        if entry is None and self.caching:
            # the same surface, the device turned no more than an orientation bin, but
            # another "up" (gravity's estimate moves with the hand's tremor): placed
            # upright again, no new solve
            def near(e: PoseEntry) -> bool:
                turned = float(np.linalg.norm(e.orientation - orientation))
                near = turned <= s.orientation_bin_rad and e.warp.content_size == content_size
                return near and unturned(e)

            base = self.poses.nearest(depth, min_frames=min_frames, accept=near, match=same)
            if base is not None:
                with self.telemetry.times.timer("re_place"):
                    cf = self.planner.with_up(base.content_free, up)
                    entry = PoseEntry(cf, base.weights, base.frames, up, base.orientation)
                self.poses.put(key, entry)
                self.telemetry.count("re_placed")
        if entry is None:
            self.telemetry.count("cache_misses")
            with self.telemetry.times.timer("content_free"):
                cf = self.planner.content_free(surface, content_size, settings)
                weights = self.display.pixel_weights(cf.warp)
                entry = PoseEntry(cf, weights, frames, up, np.asarray(orientation, np.float64))
            self.poses.put(key, entry)
            self.telemetry.count("content_free")
        else:
            self.telemetry.count("cache_hits")
        self.telemetry.counters["cache_rejected"] = self.poses.rejected
        return entry, hit

    def content_free_maps(self, entry: PoseEntry) -> RemapMaps:
        """The display maps of a content-free warp (made once per entry)."""
        if entry.maps is None:
            with self.times.timer("map"):
                entry.maps = self.display.maps(self.shown(entry.warp), entry.weights)
        return entry.maps

    def gain(self, entry: PoseEntry, surface: Surface, frames: int | None = None) -> GainMap | None:
        """The brightness gain of ``entry``'s pose (``surface``: the one it was made
        for, or one within the cache's tolerance, averaged over ``frames`` depth frames;
        None: the entry's own count), made once per entry, and again from a surface
        averaged over at least twice the frames of the one it was made from (the crease
        where its walls' planes meet, and so the jump of the gain, is placed better: a
        pixel or two off after three frames, well under one after twelve); timed as
        ``gain``; None with photometry off."""
        ph = self.settings.photometry
        if ph is None:
            return None
        frames = entry.frames if frames is None else frames
        if (
            entry.gain is not None
            and entry.gain.light.ndim == 2
            and frames >= 2 * entry.gain_frames
        ):
            entry.gain = None  # the geometric gain, from a surface averaged longer
        if entry.gain is None:
            entry.gain_frames = frames
            with self.times.timer("gain"):
                colour = self._measured_gain(surface)
                if colour is not None:
                    entry.gain = colour
                else:
                    warp = entry.warp
                    small = entry.weights.map(warp.image_xy, warp.content_size)
                    picture = np.isfinite(small[..., 0])
                    entry.gain = gain_map(surface, self.vignetting, ph, picture=picture)
        return entry.gain

    def _measured_gain(self, surface: Surface) -> GainMap | None:
        """The colour gain of :attr:`measured` (made once) when ``surface`` is still the
        one it was measured on; None (and the reason logged once) otherwise."""
        if self.measured is None:
            return None
        reason = self.measured.holds_on(surface)
        if reason is None:
            if self._colour is None:
                try:
                    m = self.measured
                    comp = plan(m.response, lift=False)
                    self._colour = colour_gain(m.response, comp, m.projector_size)
                except CalibrationError as e:
                    self._colour = str(e)
            if isinstance(self._colour, GainMap):
                return self._colour
            reason = self._colour
        if reason != self._said:
            log.info("surface colour not compensated: %s; the light is evened out alone", reason)
            self._said = reason
        return None

    def content_aware(
        self,
        surface: Surface,
        content_map: ContentMap,
        settings: WarpSettings,
        entry: PoseEntry,
        frame_dt: float | None = None,
    ) -> tuple[Warp, RemapMaps]:
        """The content-aware refinement on ``entry``'s content-free warp (made for this
        surface, or one within the pose cache's tolerance of it), and its maps.
        ``frame_dt``: a clip's frame shown that many seconds after the last (bounded
        warm steps, smoothed in time; timed as ``clip_refine``, ``clip_map``)."""
        clip = frame_dt is not None
        with self.times.timer("clip_refine" if clip else "content_aware"):
            warp = self.planner.refine(
                surface, content_map, settings, entry.content_free, frame_dt=frame_dt
            )
        with self.times.timer("clip_map" if clip else "map"):
            maps = self.display.maps(self.shown(warp), entry.weights)
        return warp, maps

    def float_map(self, warp: Warp) -> Float32Array:
        """What the display maps of ``warp`` draw, as floats (H, W, 2) (for scoring)."""
        return self.display.float_map(self.shown(warp))
