"""A session's tracking digest: what its depth frames become, in a few numbers a frame.

Replaying a session through :func:`~adaproj_edge.session.track.track_surface` and
keeping, per depth frame, the still flag, coverage, mean confidence and the depths at
five lattice nodes gives a small JSON-able record of the depth pipeline's behaviour.
``tools/make_fixtures.py --golden`` writes it for the committed sessions
(``tests/fixtures/sessions/golden.json``) and the tests compare a fresh replay with it,
field by field.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from adaproj_edge.session.player import Replay
from adaproj_edge.session.track import track_surface


def tracking_digest(path: str | os.PathLike[str], grid: tuple[int, int]) -> list[dict[str, Any]]:
    """Per depth frame of the session at ``path``: its sensor time, still flag, coverage,
    mean confidence and depths at 5 nodes.

    Parameters
    ----------
    path : path
        The session (``.mcap``).
    grid : (rows, cols)
        The lattice the surface is estimated at (e.g. (21, 21)).

    Returns
    -------
    list of dict
        One per depth frame: ``t_ns`` (int), ``still`` (bool), ``coverage`` and
        ``confidence`` (rounded to 6 places), ``z_mm`` (depth in mm, 3 places, at the
        four corner nodes and the centre node; None where unknown).
    """
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
