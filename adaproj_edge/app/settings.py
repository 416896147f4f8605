"""Tuning of the device runtime: seconds, metres, fractions (one frozen dataclass)."""

from __future__ import annotations

from dataclasses import dataclass, field

from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.planes import PlaneSettings
from adaproj_edge.motion.gravity import GravitySettings
from adaproj_edge.motion.stabiliser import StabiliserSettings
from adaproj_edge.motion.tracker import MotionSettings
from adaproj_edge.render.photometry import PhotometrySettings
from adaproj_edge.render.reproject import Interpolation
from adaproj_edge.warp.warpmap import Grid


@dataclass(frozen=True)
class DisplaySettings:
    """The display loop (:mod:`adaproj_edge.app.display_loop`): refreshes per second,
    how long before a refresh its frame is computed (seconds), how it is resampled, the
    time constant of the glide from one rendered frame's placement to the next's held
    still and turned on purpose (and the largest glide, as a share of the margin; the
    largest while the device is not turned on purpose, or from a surface's
    single-frame estimate to its average after a move, as a share of the frame), and
    the stabiliser (its ``margin`` 0: frames shown as
    rendered)."""

    refresh_hz: float = 60.0
    lead_s: float = 0.008
    interpolation: Interpolation = "nearest"
    glide_s: float = 0.3
    glide_moving_s: float = 0.05
    max_glide: float = 2.0
    max_handover_glide: float = 0.25
    stabiliser: StabiliserSettings = field(default_factory=StabiliserSettings)


@dataclass(frozen=True)
class AppSettings:
    """Tuning of the runtime (seconds, metres, fractions)."""

    grid: Grid = field(default_factory=Grid)
    capture_frames: int = 3
    capture_timeout_s: float = 0.6
    double_press_s: float = 0.35
    long_press_s: float = 0.8
    calibrate_hold_s: float = 5.0  # the hold that starts the calibration (device only)
    moving_interval_s: float = 0.1
    still_interval_s: float = 0.2
    hysteresis_rel: float = 0.004
    refine_at_frames: tuple[int, ...] = (3, 6, 12)
    settle_frames: int = 3  # depth frames averaged before the refinement once settled
    depth_timeout_s: float = 0.5
    min_coverage: float = (
        0.3  # of the lattice measured by a frame (before the cuts): less is a dropout
    )
    pose_cache_size: int = 6
    caching: bool = True
    warm_start: bool = True
    map_scale: int = 4
    refine_factor: int = 2  # the content-aware grid is this many times coarser
    refine_iterations: int = 6  # per update; the next refinement goes on from there
    keep_shown_map: bool = False  # keep the float map of the frame shown (for scoring)
    history: int = 20000  # events, updates and stage times kept (oldest dropped first)
    # a cached warp serves a surface whose depth differs from its own by what the depth
    # sensor's noise makes (posecache.surfaces_agree): a mean shift within the hand's
    # sway (m) and this many of its sigma over the nodes compared, an RMS about it
    # within this many of one pixel's sigma, and this share of the nodes known in both
    cache_sway_m: float = 0.01
    cache_match_sigmas: float = 3.0
    cache_spread_sigmas: float = 1.0
    # (not lower: served a warp made for an estimate with a border hole 3-6 % of the
    # lattice, the convex column's 4-s session of seed 0 at 0.05 deg read jitter 0.21
    # against 0.13, the fresh solve that follows re-placing the content)
    cache_overlap: float = 0.97
    cache_turn_rad: float = 0.01  # and turned in frame P at most this much (fitted planes)
    orientation_bin_rad: float = 0.03
    depth_bin_m: float = 0.03
    up_bin_rad: float = 0.01  # "up" (gravity) in the pose cache key
    up_match_rad: float = 0.005  # a cached warp serves an "up" this close
    motion: MotionSettings = field(default_factory=MotionSettings)
    gravity: GravitySettings = field(default_factory=GravitySettings)
    display: DisplaySettings = field(default_factory=DisplaySettings)
    depth: DepthSettings = field(default_factory=DepthSettings)
    planes: PlaneSettings | None = field(default_factory=PlaneSettings)  # None: no snapping
    # the brightness gain made from the surface, per pose (None: frames as rendered)
    photometry: PhotometrySettings | None = None

    def grid_shape(self) -> tuple[int, int]:
        """The surface lattice: one node per warp grid vertex."""
        return self.grid.rows + 1, self.grid.cols + 1
