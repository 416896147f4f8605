"""A new estimate of the same surface keeps the content where it was.

The device is held still in front of the built-in corner (no tremor, no sway: the
true picture does not move) and every depth frame's surface, averaged as the runtime
averages a still hand's, is placed by one planner (the runtime's: coarse-to-fine,
a content-free warp per estimate). A fresh inscribed-rectangle search on each estimate
landed in one local optimum or another and moved the content's centre along the
corner's ridge by tens of pixels between consecutive estimates (beyond the display's
glide); anchored to the last placement (``PlanSettings.anchor_rel``) it stays put.
The anchor is off in the runtime for now (``docs/handheld.md``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.app.content import builtin_item
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.surfaces import SurfaceSource
from adaproj_edge.app.telemetry import StageTimes
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.temporal import SurfaceFilter
from adaproj_edge.render.content_points import frame_pixels
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session
from adaproj_edge.session.stereo import StereoNoise
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import WarpCache
from adaproj_edge.warp.planner import PlanSettings, WarpPlanner

SECONDS = 1.0


def _centres(path: Path, hand: HandMotion) -> np.ndarray:
    """The content centre's projector pixel (N, 2) of each averaged estimate."""
    ses = read_session(path)
    s = AppSettings()
    src = SurfaceSource(ses.calibration, s, StageTimes())
    plan = PlanSettings(refine_factor=s.refine_factor, warm_start=s.warm_start, anchor_rel=0.03)
    planner = WarpPlanner(ses.calibration.projector, s.grid, plan, WarpCache())
    size = builtin_item().size
    up = hand.steady_rotation(np.array([0.0]))[0].T @ np.array([0.0, -1.0, 0.0])
    settings = WarpSettings(mode="content", grid=s.grid, up=(up[0], up[1], up[2]))
    centre = np.array([[0.5 * (size[0] - 1), 0.5 * (size[1] - 1)]])
    filt = SurfaceFilter()
    out = []
    for k, frame in enumerate(ses.depth):
        est = filt.update(src.estimate(frame), still=k > 0)
        cf = planner.content_free(src.prepared(est), size, settings)
        out.append(frame_pixels(cf.warp, centre)[0])
    return np.array(out)


@pytest.mark.parametrize(
    ("seed", "roll", "sensor"),
    [(0, 12.0, "smooth"), (1, 0.0, "smooth"), (1, 0.0, "oak-d")],
)
def test_the_corners_content_does_not_jump_between_estimates(
    tmp_path: Path, seed: int, roll: float, sensor: str
) -> None:
    hand = HandMotion(
        SECONDS, seed=seed, tremor_deg=0.0, sway_deg=0.0, move_rad=0.0, move_m=0.0,
        roll_deg=roll,
    )  # fmt: skip
    path = tmp_path / "corner.mcap"
    settings = SimulationSettings(
        seconds=SECONDS, seed=seed, motion=hand, stereo=StereoNoise.named(sensor)
    )
    simulate_session(Scene.load("corner"), path, Calibration.default(), settings)
    centres = _centres(path, hand)
    assert np.all(np.isfinite(centres))
    moves = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    # the device does not move, so the truth does not either: what an estimate may
    # move the centre by is the surface's own noise carried to the frame, a few
    # millimetres at 1.5 m (~1.2 px per mm here); a jump along the ridge was 15-50 px
    assert moves.max() < 6.0, np.round(moves, 1)
