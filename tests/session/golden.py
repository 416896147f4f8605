"""Replay outputs compared field by field with committed golden values.

The golden file (tests/fixtures/sessions/golden.json) is written only by
``tools/make_fixtures.py --golden``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from adaproj_edge.session.player import Replay
from adaproj_edge.session.track import track_surface


def replay_outputs(path: Path, grid: tuple[int, int]) -> list[dict[str, Any]]:
    """Per depth frame: still flag, coverage, confidence, and depths at 5 nodes (mm)."""
    replay = Replay(path)
    out = []
    for tr in track_surface(replay.events(), replay.calibration, grid):
        z = tr.estimate.surface.points[..., 2]
        r, c = z.shape
        probes = [(0, 0), (0, c - 1), (r // 2, c // 2), (r - 1, 0), (r - 1, c - 1)]
        out.append(
            {
                "t_ns": tr.frame.sensor_ns,
                "still": tr.still,
                "coverage": round(tr.estimate.coverage, 6),
                "confidence": round(tr.estimate.mean_confidence, 6),
                "z_mm": [
                    None if np.isnan(z[i, j]) else round(float(z[i, j]) * 1000, 3)
                    for i, j in probes
                ],
            }
        )
    return out
