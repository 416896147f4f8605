"""Relative irradiance from the surface: cos(incidence) / d^2 on planes and on the two
walls of a corner against the analytic geometry, normals beside a crease taken from
their own wall, and the vignetting field of the calibration (default none, checked)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import Corner, Plane, simulate_surface
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.irradiance import Vignetting, relative_irradiance, surface_normals
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.hal.board import Board

PROJECTOR = Projector.default(320, 200)

# The surfaces are float32 point maps: a point's relative rounding is 6e-8, a tangent
# between neighbours 1.5 m away and ~5 mm apart carries 1.5 * 6e-8 / 5e-3 ~ 2e-5 of
# it, and so do the normal and cos / d^2 to first order; 1e-4 is five times that and
# still far below any wrong term (a missing cos is 30 %, a d instead of d^2 is 50 %).
REL = 1e-4


def _irradiance(surface_points: np.ndarray) -> np.ndarray:
    uv = PROJECTOR.pixel_grid()
    return relative_irradiance(surface_points.astype(np.float64), PROJECTOR, uv)


def _expected_plane(normal: np.ndarray, offset: float) -> np.ndarray:
    """cos / d^2 of each pixel's ray on the plane n . X = offset, from the plane alone."""
    rays = PROJECTOR.rays(PROJECTOR.pixel_grid())
    unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    t = offset / (unit @ normal)
    return np.asarray(np.abs(unit @ normal) / t**2)


@pytest.mark.parametrize("theta_deg", [0.0, 20.0, 45.0, 60.0])
@pytest.mark.parametrize("dist", [1.0, 2.5])
def test_tilted_plane_gives_cos_over_d_squared(theta_deg: float, dist: float) -> None:
    a = np.deg2rad(theta_deg)
    n = np.array([np.sin(a), 0.0, -np.cos(a)])
    plane = Plane("t", (float(n[0]), 0.0, float(n[2])), float(n @ [0.0, 0.0, dist]))
    e = _irradiance(simulate_surface(plane, PROJECTOR).points)
    want = _expected_plane(n, float(n @ [0.0, 0.0, dist]))
    ok = np.isfinite(want)
    assert np.all(np.isfinite(e[ok]))
    np.testing.assert_allclose(e[ok], want[ok], rtol=REL)
    # on the optical axis (a 3x3 patch of pixels around the principal point): the
    # irradiance is cos(theta) / dist^2, the frontal plane's times cos(theta); float64
    # points 1 px (~5 mm) apart at 2.5 m carry 2.5 * 1e-16 / 5e-3 ~ 5e-14 of rounding
    cx, cy = PROJECTOR.K[0, 2], PROJECTOR.K[1, 2]
    gy, gx = np.mgrid[-1:2, -1:2].astype(np.float64)
    uv = np.stack([gx + cx, gy + cy], axis=-1)
    rays = PROJECTOR.rays(uv)
    on_axis = []
    for normal in (n, np.array([0.0, 0.0, -1.0])):
        pts = rays * ((normal @ [0.0, 0.0, dist]) / (rays @ normal))[..., None]
        on_axis.append(relative_irradiance(pts, PROJECTOR, uv)[1, 1])
    assert on_axis[1] == pytest.approx(1 / dist**2, rel=1e-12)
    assert on_axis[0] / on_axis[1] == pytest.approx(np.cos(a), rel=1e-9)


def test_corner_walls_against_their_planes() -> None:
    corner = Corner("c", x0=0.13, z0=1.8)
    pts = simulate_surface(corner, PROJECTOR).points
    e = _irradiance(pts)
    side = corner.patch(np.nan_to_num(pts))
    ratios = []
    for wall, sign in ((0, -1.0), (1, 1.0)):
        a = corner.half_angle
        tangent = np.array([sign * np.sin(a), 0.0, -np.cos(a)])
        n = np.cross(tangent, [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        want = _expected_plane(n, float(n @ [corner.x0, 0.0, corner.z0]))
        mine = side == wall
        np.testing.assert_allclose(e[mine], want[mine], rtol=REL)
        ratios.append(float(np.median(want[mine])))
    # the two walls are lit differently (the projector is off the corner's bisector)
    assert abs(ratios[0] / ratios[1] - 1) > 0.05


def test_normals_beside_a_crease_are_their_own_walls() -> None:
    """A node one pixel from the crease takes its tangents from its own side (central
    differences across the crease would give the mean of both walls' normals)."""
    corner = Corner("c", x0=0.0, z0=1.5)
    pts = simulate_surface(corner, PROJECTOR).points.astype(np.float64)
    n = surface_normals(pts)
    side = corner.patch(np.nan_to_num(pts))
    row = PROJECTOR.height // 2
    cols = np.nonzero(np.diff(side[row]))[0]
    assert cols.size == 1
    left, right = int(cols[0]), int(cols[0]) + 1  # the last pixel of each wall
    s = np.sqrt(0.5)
    np.testing.assert_allclose(n[row, left], [s, 0.0, -s], atol=1e-3)
    np.testing.assert_allclose(n[row, right], [-s, 0.0, -s], atol=1e-3)


def test_vignetting_falloff() -> None:
    v = Vignetting((-0.5, 0.1))
    c = np.array([[(PROJECTOR.width - 1) / 2, (PROJECTOR.height - 1) / 2]])
    assert v.at(PROJECTOR, c)[0] == pytest.approx(1.0)
    corner = np.array([[0.0, 0.0]])
    r = PROJECTOR.rays(corner)[0]
    r2 = r[0] ** 2 + r[1] ** 2
    assert v.at(PROJECTOR, corner)[0] == pytest.approx(1 - 0.5 * r2 + 0.1 * r2 * r2)
    assert Vignetting().none and Vignetting(()).none and not v.none
    # the irradiance carries the falloff
    plane = simulate_surface(Plane("p", (0.0, 0.0, -1.0), -1.5), PROJECTOR).points
    uv = PROJECTOR.pixel_grid()
    plain = relative_irradiance(plane.astype(np.float64), PROJECTOR, uv)
    dimmed = relative_irradiance(plane.astype(np.float64), PROJECTOR, uv, v)
    np.testing.assert_allclose(dimmed / plain, v.at(PROJECTOR, uv), rtol=1e-12)


def test_calibration_vignetting_default_none_and_round_trip() -> None:
    nominal = Board.load("rpi5-oakd").calibration()
    assert nominal.vignetting.none
    assert "vignetting" not in nominal.to_dict()["projector"]
    d = nominal.to_dict()
    d["projector"]["vignetting"] = [-0.4, 0.05]
    cal = Calibration.from_dict(d)
    assert cal.vignetting.coefficients == (-0.4, 0.05)
    for back in (
        Calibration.from_dict(tomllib.loads(cal.to_toml())),
        Calibration.from_json(cal.to_json()),
    ):
        assert back.vignetting == cal.vignetting


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ([0.1, 0.2, 0.3], "at most 2"),
        ("strong", "at most 2"),
        ([float("nan")], r"vignetting\[0\]"),
        ([True], r"vignetting\[0\]"),
        ([-20.0], r"vignetting\[0\]"),
        ([-9.0], "relative illumination"),  # negative at the frame's corners
        ([5.0], "relative illumination"),  # brighter edges than centre: not a lens
    ],
)
def test_bad_vignetting_is_refused(value: object, match: str) -> None:
    d = Calibration.default().to_dict()
    d["projector"]["vignetting"] = value
    with pytest.raises(InputError, match=match):
        Calibration.from_dict(d)
