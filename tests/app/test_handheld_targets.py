"""Issue 14's hand-held targets on sessions simulated here (the settings of
``tools/bench_handheld.py``: hand tremor 0.15 degrees RMS, still phases of 1 s between
deliberate moves), scored on the simulator's truth:

- at a wall corner, the frame-to-frame jitter while held still is at most a fifth of
  the runtime's without stabilisation (a new rendered frame once moved the content by
  centimetres along the corner's ridge: placement; and the averaged surface's
  placement replaced the last single-frame one's at once when the hand stopped);
- held still for 12 s, the picture drifts less than 2 mm over 10 s (the follower once
  started on that instant's tremor and let it decay as a drift);
- on a device rolled 20 degrees, the content stays within a degree of upright while
  held still, the settling after a move included (frames published while turning once
  glided from the last one's lag).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from adaproj_edge.app.replay import ReplayOptions, replay_session
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session


@functools.cache
def _session(tmp: str, surface: str, hand: HandMotion) -> Path:
    path = Path(tmp) / f"{Path(surface).stem}-{hand.seed}.mcap"
    settings = SimulationSettings(seconds=hand.seconds, depth_fps=15.0, seed=hand.seed, motion=hand)
    simulate_session(Scene.load(surface), path, Calibration.default(), settings)
    return path


def _handheld(path: Path, stabilise: bool) -> dict[str, Any]:
    # the hand-held measures only: no distortion scores (not read here)
    options = ReplayOptions(stabilise=stabilise, distortion=False)
    out: dict[str, Any] = replay_session(path, None, options)["handheld"]
    return out


@pytest.mark.parametrize(
    ("seconds", "seed", "tremor", "roll"),
    [(5.0, 32, 0.15, 0.0), (4.0, 0, 0.05, 0.0), (4.0, 0, 0.5, 12.0)],
)
def test_jitter_at_a_wall_corner_is_a_fifth_of_today_s(
    tmp_path: Path, seconds: float, seed: int, tremor: float, roll: float
) -> None:
    """The ratio is the summary's own: the stabilised picture's frame-to-frame motion
    over the frames as rendered, both on the simulator's true corner in the same replay
    (the bench's figure). When the hand stops after a move, the placement of the last
    single-frame surface (its depth holes: nodes missing, the rectangle up to a quarter
    smaller and a tenth of the frame away) was replaced at once by the averaged
    surface's, one jump of about 10 cm (the ratio 0.94 on seed 0 at 0.05 degrees; seed 32 at
    0.15, once marked as a known failure, likewise); the display loop now glides
    across that hand-over. At 0.5 degrees of tremor (roll 12, seed 0) the rate the
    low-pass leaves of the tremor went over the stabiliser's ``moving_rate`` while the
    hand held still, and a one-frame surface's re-placement (0.13 of the frame) was
    taken for a frame following a deliberate turn and shown at once: a jump of 188 mm,
    ratio 0.61; a turn is now told by the rate's mean over a quarter of a second."""
    hand = HandMotion(seconds, seed=seed, tremor_deg=tremor, roll_deg=roll)
    on = _handheld(_session(str(tmp_path), "corner", hand), True)
    assert on["jitter_off_mm_rms"] > 2.0
    assert on["jitter_ratio"] <= 0.2


def test_the_picture_drifts_under_2_mm_over_10_s_held_still(tmp_path: Path) -> None:
    hand = HandMotion(12.0, seed=40, tremor_deg=0.15, hold_after=0)
    on = _handheld(_session(str(tmp_path), "plane", hand), True)
    assert on["drift_mm_10s"] is not None and on["drift_mm_10s"] < 2.0


@pytest.mark.parametrize("roll", [0.0, 20.0])
def test_content_stays_within_a_degree_of_upright_on_a_rolled_device(
    tmp_path: Path, roll: float
) -> None:
    hand = HandMotion(5.0, seed=50 + int(roll) // 10, tremor_deg=0.15, roll_deg=roll)
    on = _handheld(_session(str(tmp_path), "plane", hand), True)
    assert on["upright_error_deg_max"] is not None and on["upright_error_deg_max"] <= 1.0


@pytest.mark.parametrize(("seed", "tremor", "roll"), [(1, 0.3, 12.0), (0, 0.05, 30.0)])
def test_a_shaky_hand_keeps_the_content_upright_on_a_turned_wall(
    tmp_path: Path, seed: int, tremor: float, roll: float
) -> None:
    """0.3 degrees RMS of tremor on a device rolled 12 degrees, swung on the wrist's
    lever, in front of a wall turned 35 degrees: the accelerometer alone is off by tens
    of degrees sample by sample (the content once fell back to the projector's own up,
    the roll's 12 degrees off). The worst of seeds 0 and 1 (``tools/bench_handheld.py
    --only sweep --seeds 2 --seconds 4 --tremors 0.3 --rolls 12 --full 2``): seed 1's
    hand turns the device a degree or two in front of the wall, and the pose cache once
    served the warp of the wall as it was before (depths within a percent), tipping the
    content 1.8 degrees while the up alone was within 0.12. Seed 0 at 0.05 degrees on a
    device rolled 30: the up alone is within 0.31 degrees, but the content-aware solve
    turned the mesh under the content by a degree while the refinement kept the start's
    rotation of the content (1.11 degrees off upright, now 0.45)."""
    from adaproj_edge.geometry.mesh_surface import MeshSurface, ply_bytes

    c, s = np.cos(np.radians(35.0)), np.sin(np.radians(35.0))
    v = np.array([[x * c, y, 1.5 + x * s] for x, y in ((-3, -2), (3, -2), (3, 2), (-3, 2))])
    mesh = tmp_path / "wall-35.ply"
    mesh.write_bytes(ply_bytes(MeshSurface("wall-35", v, np.array([[0, 1, 2], [0, 2, 3]]))))
    hand = HandMotion(4.0, seed=seed, tremor_deg=tremor, roll_deg=roll)
    on = _handheld(_session(str(tmp_path), str(mesh), hand), True)
    assert on["upright_error_deg_max"] is not None and on["upright_error_deg_max"] <= 1.0
    assert on["motion_to_photon_ms"]["p95"] <= 20.0
