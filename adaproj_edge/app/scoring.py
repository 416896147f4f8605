"""What a replay shows of the projection itself.

:class:`Scorer`: the distortion of the displayed map on the true surface at the true
pose, next to the warp computed from the true surface and to a plain projector (no
pre-warp). Only simulated sessions carry the truth (``truth-surface.json`` and
``/truth/pose``). The measures (:mod:`adaproj_edge.warp.quality`) are :data:`MEASURES`.

:class:`SideViews`: a few moments seen by a person off to the side, the plain projector
beside the frame shown, on the true surface (or, without truth, on the surface the
device estimated).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from adaproj_edge.app.runtime import Runtime
from adaproj_edge.arrays import Float32Array, Image
from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.display_maps import display_float_map
from adaproj_edge.render.frame import render_frame
from adaproj_edge.render.viewer import DEFAULT_VIEWER, view, viewer_for
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.simulator import Scene, scoring_projector, true_surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.quality import measure

MEASURES = {
    "angle_error": "mean over the frame of sigma1/sigma2 - 1 of the content->surface "
    "Jacobian (dimensionless; 0: no shear, 0.1: a square seen as a 1.1:1 rectangle)",
    "size_inconsistency": "std of log(sqrt(sigma1 sigma2)) over the frame (dimensionless; "
    "0: the content keeps one scale everywhere, 0.1: sizes vary by about 10 %)",
    "salient_*": "the same over the salient content only",
    "shown_*": "the frame the device showed, on the true surface at the true pose",
    "truth_*": "the warp computed from the true surface (full grid, full refinement)",
    "plain_*": "a plain projector (the content letterboxed, no pre-warp), the baseline",
}
"""What the distortion figures of a replay summary mean."""


class Scorer:
    """Distortion on the true surface: displayed map vs the warp from the truth.

    Parameters
    ----------
    scene : Scene
        The session's true surface.
    runtime : Runtime
        The runtime being replayed (it keeps the float map of each content-aware frame).
    attachments : dict of str to bytes
        The session's attachments (a simulated session's true rig, when it has one, is
        the projector that really lights the surface).
    """

    def __init__(self, scene: Scene, runtime: Runtime, attachments: dict[str, bytes]) -> None:
        self.scene = scene
        self.rt = runtime
        # the projector that really lights the surface (a simulated session's true rig)
        self.projector = scoring_projector(attachments, runtime.calibration.projector)
        self.scores: list[dict[str, Any]] = []
        self.last_truth: Surface | None = None
        self._plain: dict[tuple[int, int], Float32Array] = {}

    def score(self, pose: TruthPose) -> None:
        """Score the frame shown now, seen at the true ``pose``."""
        rt = self.rt
        item = rt.item
        if rt.shown_map is None or item.content_map is None:
            return
        truth = true_surface(self.scene, pose, self.projector, (101, 161))
        # the engine's warp on the true surface: full grid, full refinement, on the
        # device's grid (compute_warp would add lines where the surface bends)
        settings = WarpSettings(
            mode="content",
            grid=rt.settings.grid,
            threshold=item.settings.threshold,
            adaptive=False,
        )
        try:
            ref_map: Float32Array | None = display_float_map(
                compute_warp(truth, item.size, item.content_map, settings), rt.settings.map_scale
            )
        except WarpError:  # a true surface with silhouettes may fold on the device's grid
            ref_map = None
        plain_map = self._plain.get(item.size)
        if plain_map is None:
            plain_map = display_float_map(rt.warps.planner.standard(item.size), 1)
            self._plain[item.size] = plain_map
        salient = item.content_map.full_size() >= item.content_map.threshold
        entry: dict[str, Any] = {"t_ns": rt.clock.now_ns()}
        for name, m in (("shown", rt.shown_map), ("truth", ref_map), ("plain", plain_map)):
            if m is None:  # no warp from the truth: its figures are NaN
                for key in ("angle_error", "size_inconsistency"):
                    entry[f"{name}_{key}"] = entry[f"{name}_salient_{key}"] = float("nan")
                continue
            overall, sal = measure(m, truth, salient)
            assert sal is not None
            entry[f"{name}_angle_error"] = round(overall.angle_error, 5)
            entry[f"{name}_size_inconsistency"] = round(overall.size_inconsistency, 5)
            entry[f"{name}_salient_angle_error"] = round(sal.angle_error, 5)
            entry[f"{name}_salient_size_inconsistency"] = round(sal.size_inconsistency, 5)
        self.scores.append(entry)
        self.last_truth = truth


class SideViews:
    """A few moments of a replay seen from the side, plain projector | frame shown.

    Offered moments are kept evenly spaced (at most ``2 * count``, the stride doubling
    as they come); the pictures, which cost about a second each, are made for
    ``count`` of them at the end.

    Parameters
    ----------
    runtime : Runtime
    count : int
        Moments in the picture.
    """

    def __init__(self, runtime: Runtime, count: int = 3) -> None:
        self.rt = runtime
        self.count = count
        self.offered = 0
        self.stride = 1
        self._kept: list[tuple[int, Surface, Image, str]] = []

    def offer(self, surface: Surface, truth: bool) -> None:
        """The frame shown now, on ``surface`` (the truth, or the device's estimate)."""
        self.offered += 1
        if (self.offered - 1) % self.stride:
            return
        shown = self.rt.output.clean_frame
        if shown is None:
            return
        where = "true surface" if truth else "estimated surface"
        self._kept.append((self.rt.clock.now_ns(), surface, shown.copy(), where))
        if len(self._kept) > 2 * self.count:
            self.stride *= 2
            self._kept = self._kept[::2]

    def pictures(self, t0: int) -> list[tuple[list[Image], list[str]]]:
        """Rows of (plain, shown) pictures from the side, with captions."""
        if not self._kept:
            return []
        idx = np.unique(np.linspace(0, len(self._kept) - 1, self.count).round().astype(int))
        item = self.rt.item
        plain = render_frame(item.image, self.rt.warps.plain(item.size)[1])
        out = []
        for i in idx:
            t_ns, surface, shown, where = self._kept[i]
            viewer = viewer_for(surface, DEFAULT_VIEWER)
            t = (t_ns - t0) / 1e9
            out.append(
                (
                    [view(surface, plain, viewer), view(surface, shown, viewer)],
                    [
                        f"{t:.2f}s plain projector, from the side ({where})",
                        f"{t:.2f}s adaproj, from the side",
                    ],
                )
            )
        return out
