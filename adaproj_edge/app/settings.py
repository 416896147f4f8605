"""Tuning of the device runtime: seconds, metres, fractions (one frozen dataclass)."""

from __future__ import annotations

from dataclasses import dataclass, field

from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.planes import PlaneSettings
from adaproj_edge.motion.tracker import MotionSettings
from adaproj_edge.warp.warpmap import Grid


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
