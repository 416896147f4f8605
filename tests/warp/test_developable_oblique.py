"""Developable surfaces the built-in set lacks are exact on the displayed map too: cones
on their own (not meeting a wall), cylinders whose axis is neither vertical nor
horizontal in the frame, and wall corners seen tilted and rolled (the crease oblique).

Issue 30's line for every developable surface: mean angle error and size inconsistency
<= 5e-4 on the displayed map, measured every 4 px. Ground truth: the independent scorer
(``tests/distortion.py``: the rendered per-pixel map against rays cast at the analytic
surface); the surfaces are the analytic classes of
:mod:`adaproj_edge.geometry.analytic`, turned about the projector by
:class:`tests.warp.random_surfaces.Turned`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import SURFACES, ConeWall, Corner, Cylinder, simulate_surface
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from tests.distortion import measure
from tests.warp.conftest import CONTENT, subject_masks
from tests.warp.random_surfaces import Turned, axis_angle

EXACT = 5e-4  # the line (exact surfaces score ~5e-5 here)


def turned(surface: Any, pitch: float, yaw: float, roll: float) -> Turned:
    """``surface`` turned by ``pitch``, ``yaw`` and ``roll`` degrees about the
    projector's x, y and z axes (in that order of application: roll first)."""
    rot = (
        axis_angle(np.deg2rad([pitch, 0.0, 0.0]))
        @ axis_angle(np.deg2rad([0.0, yaw, 0.0]))
        @ axis_angle(np.deg2rad([0.0, 0.0, roll]))
    )
    return Turned(surface, tuple(tuple(float(v) for v in row) for row in rot))


# a cone whose ruling meeting the wall is out of the frame: only the cone is seen
CONE = ConeWall("cone", x0=-0.7, z0=1.6, apex_y=-1.4, alpha=0.3, turn=0.3)
WIDE_CONE = ConeWall("wide-cone", x0=-0.7, z0=1.8, apex_y=-0.9, alpha=0.5, turn=0.2)
# the built-in cone meeting a wall along its ruling (the paper's Figure 11)
CONE_WALL = ConeWall("cone-wall", x0=-0.12, z0=1.6, apex_y=-1.4, alpha=0.3, turn=0.35)
CASES = [
    # the cone rolled 60 deg, seen up to 78 deg from its normal where it turns away:
    # each pixel projected onto its triangle's plane (a chord) fell short of where the
    # development puts it by the triangle's turn squared (mean angle 2.9e-4, size
    # 6.3e-4); placed from its developed distances to the corners, 8.3e-5 and 1.8e-4
    pytest.param(turned(CONE, 0.0, 0.0, 60.0), id="cone-rolled"),
    pytest.param(WIDE_CONE, id="wide-cone"),
    # the wide cone rolled 90 deg, its rulings along the rows: the chords' shortfall
    # again (3.7e-4, 5.3e-4; at 70 deg, before the seams' blend was widened and its
    # cells split to turns of 0.05, 8.3e-4 and 9.8e-4), 4.6e-5 and 8.1e-5 developed
    pytest.param(turned(WIDE_CONE, 0.0, 0.0, 90.0), id="wide-cone-rolled"),
    # the cone meeting a wall rolled 75 deg: the adaptive grid's cells run 64 x 8 px
    # along the crease, and a cell's centroid half a pixel past it was sampled across
    # it (on neither side's patch), so its triangles were left chords across the
    # crease and the display blended them into their unfolded neighbours: a band two
    # cells long (mean angle 9.9e-5, size 7.2e-4); 4.8e-5 and 2.8e-4 since
    pytest.param(turned(CONE_WALL, 0.0, 0.0, 75.0), id="cone-wall-rolled"),
    pytest.param(
        turned(Cylinder("column", cx=0.0, cz=2.3, r=0.75, concave=False), 25.0, 20.0, 0.0),
        id="column-oblique",
    ),
    pytest.param(
        turned(Cylinder("vault", cx=0.0, cz=0.45, r=1.25, concave=True), -20.0, 30.0, 15.0),
        id="vault-oblique",
    ),
    # a 60 deg corner tilted and rolled 90 deg: the second wall is a strip along the
    # frame's top edge, narrower than the row of cells the crease runs through, so none
    # of its triangles is flat; its vertices borrowed the first wall's plane and the
    # crease went unfolded: a band a cell wide along it (mean angle 6.9e-3, size 2.4e-2)
    pytest.param(
        turned(Corner("c60", x0=0.1, z0=1.8, half_angle=np.deg2rad(30)), 15.0, -20.0, 90.0),
        id="corner60-rolled",
    ),
    # a 90 deg corner tilted and rolled 45 deg: the crease clips the frame's top-left
    # corner cells, the same way (1.2e-3, 5.8e-3)
    pytest.param(
        turned(Corner("corner", x0=0.13, z0=1.8), 15.0, -20.0, 45.0),
        id="corner90-rolled",
    ),
    # the wavy wall rolled 60 deg: its rulings run obliquely, the grid is split both
    # ways to its vertex budget and each cell spans a sixth of a wave (turns up to 0.4).
    # A pixel placed from its developed distances to the corners as if on an arc of
    # constant curvature (the corner's normal alone), and not at all where a corner's
    # normal leaned out of the plane by more than 0.3, missed the crests and troughs
    # (mean angle 1.3e-3); placed as on a cubic with its own normal too, 3.5e-4, 1.9e-4
    pytest.param(turned(SURFACES["waves"], 0.0, 0.0, 60.0), id="waves-rolled"),
]


@pytest.mark.parametrize("analytic", CASES)
def test_cones_and_oblique_cylinders_are_exact_on_the_display(analytic: Any) -> None:
    surface = simulate_surface(analytic)
    warp = compute_warp(surface, CONTENT, subject_masks()["half"], WarpSettings(mode="content"))
    d = measure(map_from_warp(warp, surface), analytic, surface.projector.K)
    assert d.folds == 0
    assert d.angle_mean <= EXACT and d.size_std <= EXACT, (d.angle_mean, d.size_std)
