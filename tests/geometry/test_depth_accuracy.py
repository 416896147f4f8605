"""Done-when: on simulated sessions with realistic noise, the surface at the warp grid
vertices is within 5 mm (median) and 15 mm (p95) of the ground truth at ~1.5 m."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.simulator import (
    Scene,
    SimulationSettings,
    scene_of_session,
    simulate,
    true_surface,
)
from adaproj_edge.session.track import track_surface

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "sessions"
GRID = (21, 21)  # vertices of a 20x20 warp grid


def grid_errors(records: list, calibration: Calibration, scene: Scene) -> np.ndarray:  # type: ignore[type-arg]
    poses = {r.t_ns: r for r in records if isinstance(r, TruthPose)}
    errs = []
    for tr in track_surface(records, calibration, GRID):
        truth = true_surface(scene, poses[tr.frame.sensor_ns], calibration.projector, GRID)
        e = np.linalg.norm(tr.estimate.surface.points - truth.points, axis=-1)
        errs.append(e[np.isfinite(e)])
    return np.concatenate(errs)


@pytest.mark.parametrize("name", ["corner", "cylinder", "sphere", "mesh-sphere"])
def test_fixture_sessions_meet_the_accuracy_target(name: str) -> None:
    s = read_session(FIXTURES / f"{name}.mcap")
    spec = s.truth_surface_spec()
    assert spec is not None
    scene = scene_of_session(spec, s.attachments)
    e = grid_errors(s.records, s.calibration, scene)
    assert e.size > 0.5 * 15 * GRID[0] * GRID[1]
    assert np.median(e) < 0.005, f"median {1000 * np.median(e):.2f} mm"
    assert np.percentile(e, 95) < 0.015, f"p95 {1000 * np.percentile(e, 95):.2f} mm"


def test_plane_at_one_and_a_half_metres() -> None:
    cal = Calibration.default()
    scene = Scene.load("plane")
    recs = simulate(scene, cal, SimulationSettings(seconds=2.0, depth_fps=5.0, seed=5))
    e = grid_errors(recs, cal, scene)
    assert np.median(e) < 0.005 and np.percentile(e, 95) < 0.015
