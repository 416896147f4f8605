"""Ground-truth scoring of a replay: the distortion of the displayed map on the true
surface at the true pose, next to the warp computed from the true surface.

Only simulated sessions carry the truth (``truth-surface.json`` and ``/truth/pose``).
"""

from __future__ import annotations

from typing import Any

from adaproj_edge.app.runtime import Runtime
from adaproj_edge.render.display_maps import display_float_map
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.simulator import Scene, true_surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.quality import measure


class Scorer:
    """Distortion on the true surface: displayed map vs the warp from the truth.

    Parameters
    ----------
    scene : Scene
        The session's true surface.
    runtime : Runtime
        The runtime being replayed (it keeps the float map of each content-aware frame).
    """

    def __init__(self, scene: Scene, runtime: Runtime) -> None:
        self.scene = scene
        self.rt = runtime
        self.scores: list[dict[str, Any]] = []

    def score(self, pose: TruthPose) -> None:
        """Score the frame shown now, seen at the true ``pose``."""
        rt = self.rt
        item = rt.item
        if rt.shown_map is None or item.content_map is None:
            return
        proj = rt.calibration.projector
        truth = true_surface(self.scene, pose, proj, (101, 161))
        settings = WarpSettings(
            mode="content", grid=rt.settings.grid, threshold=item.settings.threshold
        )
        # the engine's warp on the true surface: full grid, full refinement
        ref_map = display_float_map(
            compute_warp(truth, item.size, item.content_map, settings), rt.settings.map_scale
        )
        salient = item.content_map.full_size() >= item.content_map.threshold
        shown, shown_s = measure(rt.shown_map, truth, salient)
        ref, ref_s = measure(ref_map, truth, salient)
        assert shown_s is not None and ref_s is not None
        self.scores.append(
            {
                "t_ns": rt.clock.now_ns(),
                "shown_angle_error": round(shown.angle_error, 5),
                "truth_angle_error": round(ref.angle_error, 5),
                "shown_size_inconsistency": round(shown.size_inconsistency, 5),
                "truth_size_inconsistency": round(ref.size_inconsistency, 5),
                "shown_salient_angle_error": round(shown_s.angle_error, 5),
                "truth_salient_angle_error": round(ref_s.angle_error, 5),
            }
        )
