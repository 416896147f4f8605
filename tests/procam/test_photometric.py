"""The surface's response measured from rendered captures end to end: the calibration
simulator's camera sees the Gray code and the primaries on a textured wall corner,
the captures are decoded and mapped to projector pixels, and the measured light
matches the renderer's own (its geometry and albedo, binned by the true projector
pixel); the compensation made from it evens out what the camera then sees."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.procam.graycode import PatternSet, decode
from adaproj_edge.procam.photometric import (
    Measured,
    load_beside,
    measure_pose,
    photometric_path,
    primary_frame,
    to_projector,
)
from adaproj_edge.render.photometry import apply_gain
from adaproj_edge.render.reflectance import Response, colour_gain, plan
from adaproj_edge.session.scene_render import CameraOptics, clean_capture, lit_view, render_capture
from adaproj_edge.session.simulator import Scene

SCALE = 16


def test_measured_light_matches_the_renderer_and_compensation_evens_it() -> None:
    rig = Calibration.default()
    scene = Scene.load("corner")
    size = (320, 200)
    K = rig.depth.intrinsics_at(*size)
    optics = CameraOptics(supersample=2, albedo_texture=0.4, interreflection=0.0)
    view = lit_view(scene, rig, np.eye(3), np.zeros(3), K, size, optics)
    ps = PatternSet(1280, 800)
    rng = np.random.default_rng(3)
    exposure = (14000, 400)  # brighter than the pose captures: the dim blue is ~10 levels
    images = [render_capture(view, ps.frame(i), optics, *exposure, rng) for i in range(len(ps))]
    dec = decode(images, ps)
    prim = [
        render_capture(view, primary_frame(j, (1280, 800)), optics, *exposure, rng)
        for j in range(3)
    ]
    black = render_capture(view, ps.frame(0), optics, *exposure, rng)
    white = render_capture(view, ps.frame(1), optics, *exposure, rng)
    response = measure_pose(black, white, prim, dec, (1280, 800), SCALE)
    # the truth: the renderer's light (albedo x cos / d^2, times the camera's white
    # level and exposure) binned by each camera pixel's *true* projector pixel
    light, uv = view.light, view.uv  # at the renderer's supersampling
    gain = (exposure[0] / optics.reference_exposure_us) * (exposure[1] / optics.reference_iso)
    truth = light * optics.white_level * gain * (1 - optics.black_level)
    h, w = 800 // SCALE, 1280 // SCALE
    ok = (uv[..., 0] >= 0) & (light > 0)
    ix, iy = (uv[ok, 0] / SCALE).astype(int), (uv[ok, 1] / SCALE).astype(int)
    sums = np.bincount(iy * w + ix, truth[ok], h * w)
    counts = np.bincount(iy * w + ix, None, h * w)
    true_cells = np.where(counts >= 4, sums / np.maximum(counts, 1), np.nan).reshape(h, w)
    got = response.white() @ np.array([0.114, 0.587, 0.299])  # as the grey camera sees
    both = response.valid & np.isfinite(true_cells)
    assert np.count_nonzero(both) > 0.3 * h * w
    rel = got[both] / true_cells[both]
    # the camera's blur and noise and the decode's cell quantisation: within 10 % for
    # most cells, and the albedo texture (40 %) is followed, not flattened
    assert np.median(np.abs(rel - 1)) < 0.05 and np.quantile(np.abs(rel - 1), 0.9) < 0.15
    assert np.ptp(np.log(true_cells[both])) > 0.5
    # a grey albedo: the three primaries are measured alike (no tint)
    diag = np.diagonal(response.mix, axis1=-2, axis2=-1)[response.valid]
    assert np.all(np.abs(np.median(diag / diag.mean(axis=1, keepdims=True), axis=0) - 1) < 0.05)
    # compensated grey seen by the same camera (noise free, the room's light taken
    # off: the per-frame gain leaves it where it falls) is far more even
    cg = colour_gain(response, plan(response, lift=False), (1280, 800))
    grey = np.full((800, 1280, 3), 160, np.uint8)
    off = clean_capture(view, None, optics, *exposure)

    def seen(frame: np.ndarray) -> np.ndarray:
        lit = clean_capture(view, frame, optics, *exposure) - off
        return to_projector(lit, dec, (1280, 800), SCALE)[both]

    spread = [
        np.quantile(v, 0.95) / np.quantile(v, 0.05)
        for v in (seen(grey), seen(apply_gain(grey, cg)))
    ]
    # (the rest: the measurement's own error above, and the 2 % of cells let fall short)
    assert spread[0] > 1.8 and spread[1] < 1.2, spread


def test_the_measurement_beside_the_calibration(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Written whole and read back; none beside a calibration: None; a damaged file:
    None and a warning (the geometric gain serves)."""
    h, w = 4, 6
    mix = np.broadcast_to(np.eye(3, dtype=np.float32) * 100, (h, w, 3, 3)).copy()
    r = Response(mix, np.ones((h, w, 3), np.float32), np.ones((h, w), bool))
    cal = tmp_path / "unit.toml"
    assert load_beside(cal) is None
    Measured(r, np.full((h, w), 1.5), (12, 8)).save(photometric_path(cal))
    back = load_beside(cal)
    assert back is not None and np.array_equal(back.response.mix, mix)
    assert back.projector_size == (12, 8) and np.all(back.distance_m == 1.5)
    photometric_path(cal).write_bytes(b"PK not really")
    with caplog.at_level("WARNING"):
        assert load_beside(cal) is None
    assert "surface colour not compensated" in caplog.text
