"""``adaproj simulate-calibration --albedo --ambient`` then ``adaproj calibrate``: the
surface's colour and the room's light measured from simulated captures of a tinted,
textured wall corner agree with the picture and the light put in (the truth is
computed here from the PNG and the simulator's camera parameters alone)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.hal.board import Board
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.render.reflectance import Response
from adaproj_edge.session.scene_render import CameraOptics
from tests.procam.rigs import true_rig

CHECK = 160  # projector pixels
TINTS = (np.array([0.60, 0.85, 1.00]), 0.5 * np.array([1.00, 0.90, 0.70]))  # blue, green, red
"""Beige checks and blue-grey ones at half the brightness (grey contrast 0.49)."""
GREY = np.array([0.114, 0.587, 0.299])  # the simulated grey camera's shares of the primaries
AMBIENT = 0.08


def _kind(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    return (i + j) % 2


def albedo_png(path: Path) -> np.ndarray:
    v, u = np.mgrid[0:800, 0:1280]
    kind = _kind(v // CHECK, u // CHECK)
    albedo = np.where(kind[..., None] == 0, TINTS[0], TINTS[1])
    cv2.imwrite(str(path), np.rint(255 * albedo).astype(np.uint8))
    return np.asarray(np.rint(255 * albedo) / 255, np.float64)


def assert_paint_measured(
    r: Response, albedo: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Assert that ``r`` measured the checks of :func:`albedo_png`: their tints and
    their brightness against their neighbours; the light seen of each primary (h, w,
    3), the paint per cell and the checks' insides."""
    h, w = r.valid.shape
    truth = cv2.resize(albedo, (w, h), interpolation=cv2.INTER_AREA)
    seen = np.diagonal(r.mix, axis1=-2, axis2=-1).astype(np.float64)  # per primary, less black
    # the checks' insides: 32 px from their edges (one camera pixel covers 5 projector
    # pixels: an edge is blurred over about 60 px by the camera and the decode's cells)
    u, v = ((np.arange(n) + 0.5) * s / n for n, s in ((w, 1280), (h, 800)))
    inside = (np.abs(v % CHECK - CHECK / 2) < 32)[:, None] & (np.abs(u % CHECK - CHECK / 2) < 32)
    ci, cj = (v // CHECK).astype(int)[:, None], (u // CHECK).astype(int)[None, :]
    kind = _kind(ci, cj)
    o = CameraOptics()
    # 1. the tint: each primary's share of the white seen, per kind of check, is the
    # paint's (the geometry divides out). Tolerance: the camera noise -- the median
    # over ~20 checks of ~80 camera pixels each; the dim blue of a dark check is ~3
    # camera levels with a read noise of 1.5, so its median is good to ~1.5 % (3
    # sigma: 5 %), green and red to under 1 % (2 %) -- plus the light bounced between
    # the walls (the simulator's ``interreflection`` of the mean direct light, which
    # is up to 1.5x a dark check's own) that carries the other checks' tint
    shares = [t / (t @ GREY) for t in TINTS]
    for k in (0, 1):
        cells = r.valid & inside & (kind == k)
        assert np.count_nonzero(cells) > 2000
        got = np.median(seen[cells] / (seen[cells] @ GREY)[:, None], axis=0)
        bounce = o.interreflection * 1.5 * np.abs(shares[1 - k] - shares[k]) / shares[k]
        tol = np.array([0.05, 0.02, 0.02]) + bounce
        assert np.all(np.abs(got / shares[k] - 1) < tol), (k, got, shares[k], tol)
    # 2. the texture: each check's white against the geometric mean of its two
    # neighbours (left-right and up-down: the light's falloff, nearly linear in log over
    # three checks, divides out) is the paint's (2 or 1/2). Tolerance: light bounced
    # between the walls is not textured (5 % of the mean: 3 % less contrast), the
    # falloff's curvature and the corner's crease (a few triplets: the quantile)
    white = seen @ GREY
    med = {}
    for i in range(5):
        for j in range(8):
            cells = r.valid & inside & (ci == i) & (cj == j)
            if np.count_nonzero(cells) > 50:
                med[i, j] = (float(np.median(white[cells])), float(np.mean(truth[cells] @ GREY)))
    errs = []
    for (i, j), (m0, t0) in med.items():
        for a, b in (((i, j - 1), (i, j + 1)), ((i - 1, j), (i + 1, j))):
            if a in med and b in med:
                got_ratio = m0 / np.sqrt(med[a][0] * med[b][0])
                true_ratio = t0 / np.sqrt(med[a][1] * med[b][1])
                errs.append(np.log(got_ratio / true_ratio))
    assert len(errs) > 30
    assert np.median(np.abs(errs)) < 0.06 and np.quantile(np.abs(errs), 0.8) < 0.1
    return seen, truth, inside


@pytest.mark.slow
def test_a_tinted_textured_corner_in_a_lit_room_is_measured(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    albedo = albedo_png(tmp_path / "albedo.png")
    rig = tmp_path / "rig.json"
    rig.write_text(true_rig(Board.load("rpi5-oakd").calibration(), +1, 7).to_json())
    session, out = tmp_path / "s.mcap", tmp_path / "unit.toml"
    args = ["simulate-calibration", "--surface", "corner", "--rig", str(rig), "--poses", "3"]
    args += ["--seed", "7", "--camera", "256x160", "--photometric", "--out", str(session)]
    assert main([*args, "--albedo", str(tmp_path / "albedo.png"), "--ambient", str(AMBIENT)]) == 0
    # the geometric calibration still passes on the textured surface
    assert main(["calibrate", "--replay", str(session), "--out", str(out)]) == 0
    assert "pose 1: the surface's colour and the room's light measured" in capsys.readouterr().out
    r = Measured.load(out.with_name("unit.photometric.npz")).response
    seen, truth, inside = assert_paint_measured(r, albedo)
    # 3. the room's light: the black capture less the projector's black (its share of
    # the white seen), over the light a white surface returns at the reference distance
    o, cam = CameraOptics(), Board.load("rpi5-oakd").camera
    gain = cam.exposure_us / o.reference_exposure_us * cam.iso / o.reference_iso
    bl = o.black_level
    room = (r.ambient * (1 - bl) - bl * seen) / (truth * gain * (1 - bl) * o.white_level)
    got_ambient = np.median(room[r.valid & inside], axis=0)
    assert np.all(np.abs(got_ambient - AMBIENT) < 0.1 * AMBIENT), got_ambient
