"""Tuning of the depth -> surface pipeline (metres, pixels)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DepthSettings:
    """Tuning of the depth -> surface pipeline (metres, pixels)."""

    min_depth_m: float = 0.35
    max_depth_m: float = 6.0
    speckle_rel: float = 0.03
    smooth_sigma_px: float = 0.7
    min_support: float = 0.35
    iterations: int = 8
    max_hole_nodes: int = 16
    disparity_sigma_px: float = 0.1
    sigma_ref_m: float = 0.02
    spike_rel: float = 0.02
    smooth_m: float = 0.06
    smooth_max_nodes: float = 3.0
    max_supersample: int = 4
    smooth_scales: tuple[float, ...] = (1.0, 2.0, 4.0)
    smooth_accept: float = 4.0
