"""Tuning of the depth -> surface pipeline (metres, pixels)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DepthSettings:
    """Tuning of the depth -> surface pipeline (metres, pixels).

    ``sensor`` names the kind of depth sensor
    (:data:`~adaproj_edge.geometry.depth.sensor.SENSORS`; its focal length and baseline
    come from the calibration). ``step_floor`` is how many of its inverse-depth steps a
    narrower smoothing fit may follow before a wider one is refused; ``jump_sigmas``
    how many of its depth errors (sigma(z), beyond what the surface's slope explains)
    make a depth jump between neighbouring lattice nodes a silhouette
    (:mod:`~adaproj_edge.geometry.depth.cuts`), ``flying_sigmas`` the same for a pixel
    lying between the two sides of a jump in the depth image; ``jump_ray_deg`` how
    close to the ray a depth image's neighbourhood must run (beyond that noise) to be a
    jump between the lattice's nodes (a silhouette, or the curtain of edge smoothing
    beside it, however steep the surface either side); ``cut`` = False keeps
    every piece of the lattice and the pixels at jumps (the pipeline without cuts).

    Holes in the lattice of at most ``max_hole_nodes`` nodes inside the frame are
    filled from their neighbours; with ``cut``, a larger one (up to
    ``max_fit_hole_share`` of the lattice) or one at the frame's border is filled from
    a smooth surface fitted to the known nodes within ``ring_nodes`` of it, when their
    RMS distance to it is within ``ring_sigmas`` of the sensor's error (and each
    within twice that), unless it is seen at more than ``fill_max_incidence_deg``
    from the surface's normal; at the border only ``border_fill_nodes`` deep
    (:func:`~adaproj_edge.geometry.depth.lattice.fill_from_ring`).
    """

    sensor: str = "oak-d"
    step_floor: float = 0.25
    jump_sigmas: float = 6.0
    jump_slope: float = 2.0
    jump_ray_deg: float = 5.0
    flying_sigmas: float = 4.0
    cut: bool = True
    min_depth_m: float = 0.35
    max_depth_m: float = 6.0
    speckle_rel: float = 0.03
    smooth_sigma_px: float = 0.7
    min_support: float = 0.35
    iterations: int = 8
    max_hole_nodes: int = 16
    max_fit_hole_share: float = 0.25
    ring_nodes: int = 2
    ring_sigmas: float = 1.0
    border_fill_nodes: int = 3
    fill_max_incidence_deg: float = 75.0
    disparity_sigma_px: float = 0.1
    sigma_ref_m: float = 0.02
    spike_rel: float = 0.02
    smooth_m: float = 0.06
    smooth_max_nodes: float = 3.0
    max_supersample: int = 4
    smooth_scales: tuple[float, ...] = (1.0, 2.0, 4.0)
    smooth_accept: float = 4.0
