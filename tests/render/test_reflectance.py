"""The surface's own colour and the room's light: the measured response and its
compensation on synthetic fields (exact where the projector can, graceful where it
cannot), the simulated path end to end judged against the test's own light model and
image-quality figures (tests/render/image_quality.py), and bad captures refused."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from adaproj_edge.content.builtin import poster
from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.render.photometry import apply_gain
from adaproj_edge.render.reflectance import (
    PRIMARY_WEIGHTS,
    colour_gain,
    compensate,
    measure,
    plan,
)
from adaproj_edge.render.surface_light import scaled_irradiance, simulated_captures
from tests.render.image_quality import scores

SHAPE = (40, 60)


def _fields(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A colour mixing field M (h, w, 3, 3): a tinted, textured reflectance on the
    diagonal (0.5-1.0 of 200 camera levels) with up to 10 % crosstalk, and an ambient
    offset field a (h, w, 3) of 0-20 levels."""
    rng = np.random.default_rng(seed)
    h, w = SHAPE
    rho = rng.uniform(0.5, 1.0, (h, w, 3)) * rng.uniform(0.7, 1.0, 3)
    mix = 200.0 * (rho[..., :, None] * np.eye(3) + rng.uniform(0, 0.1, (h, w, 3, 3)) * 0.2)
    return mix, rng.uniform(0.0, 20.0, (h, w, 3))


def _captures(mix: np.ndarray, amb: np.ndarray) -> list[np.ndarray]:
    """Noise-free colour captures of black, white, blue, green, red (the test's own
    model: L = M p + a)."""
    frames = [np.zeros(3), np.ones(3), *np.eye(3)]
    return [np.einsum("...ij,j->...i", mix, p) + amb for p in frames]


@pytest.mark.parametrize("seed", range(3))
def test_exact_where_the_projector_can_graceful_where_it_cannot(seed: int) -> None:
    mix, amb = _fields(seed)
    k0, kw, kb, kg, kr = _captures(mix, amb)
    response = measure(k0, kw, [kb, kg, kr])
    # the measurement recovers M and a (float64 arithmetic on values <= 255: 1e-9)
    assert np.allclose(response.mix, mix, atol=1e-3)  # stored as float32
    assert np.allclose(response.ambient, amb, atol=1e-3)
    comp = plan(response)
    target = np.random.default_rng(seed + 10).uniform(0, 1, (*SHAPE, 3))
    target[: SHAPE[0] // 2] = 1.0  # white, where the darkest pixels fall short
    p = compensate(response, comp, target)
    assert np.all((p >= 0) & (p <= 1))
    seen = np.einsum("...ij,...j->...i", mix, p) + amb
    want = comp.scale * target + comp.lift
    # unclipped pixels show the target exactly (the float32 M: relative 1e-6 of 255)
    inner = np.all((p > 1e-6) & (p < 1 - 1e-6), axis=-1)
    assert np.count_nonzero(inner) > 0.5 * inner.size
    assert np.allclose(seen[inner], want[inner], atol=1e-3)
    # pixels that cannot reach the target's brightness show less, never more (those
    # clipped at 0 are where the room alone is brighter than the asked black: the
    # lift is a quantile of the ambient)
    clipped = ~inner
    top = clipped & np.all(p > 1e-6, axis=-1)
    assert np.count_nonzero(top) > 0
    assert np.all(seen[top] <= want[top] + 1e-3)
    # where the pixel's black is reachable (p of black target inside [0, 1]) and p did
    # not clip at 0, the light above black points along the target (hue kept)
    base = compensate(response, comp, np.zeros_like(target))
    free = np.all((base > 1e-6) & (base < 1 - 1e-6), axis=-1) & np.all(p > 1e-6, axis=-1)
    shown, ask = (seen - comp.lift)[clipped & free], (want - comp.lift)[clipped & free]
    cos = np.sum(shown * ask, -1) / (np.linalg.norm(shown, axis=-1) * np.linalg.norm(ask, axis=-1))
    assert np.all(cos > 1 - 1e-6)
    # little clips: the scale is the clip quantile of what the pixels reach
    assert comp.clipped <= 0.02 + 1 / inner.size


def test_grey_camera_sees_the_tint_through_the_primaries_weights() -> None:
    """A grey camera: each primary's capture is its reflectance times the camera's
    weight; a smooth tinted field is recovered per primary within the noise-free
    smoothing error (a field varying by <= 1 % per pixel, smoothed over 2 pixels)."""
    h, w = SHAPE
    y, x = np.mgrid[0:h, 0:w]
    rho = np.stack([0.5 + 0.2 * np.sin(x / 30), 0.8 + 0.1 * np.cos(y / 25), 0.9 + 0 * x], -1)
    wt = np.asarray(PRIMARY_WEIGHTS)
    amb = 5.0
    k0 = amb * (rho @ wt)
    prim = [200 * wt[j] * rho[..., j] + k0 for j in range(3)]
    kw = 200 * (rho @ wt) + k0
    r = measure(k0, kw, prim)
    diag = np.diagonal(r.mix, axis1=-2, axis2=-1)
    assert np.allclose(diag[4:-4, 4:-4], 200 * rho[4:-4, 4:-4], rtol=0.01)
    assert np.allclose(r.ambient, amb * rho, rtol=0.02)


def _flat_captures(level: float, dark: float = 0.0) -> list[np.ndarray]:
    h, w = SHAPE
    rng = np.random.default_rng(0)
    amb = np.full((h, w), dark)
    white = np.full((h, w), level) + rng.normal(0, 1, (h, w))
    return [amb, white + amb, *(wt * white + amb for wt in PRIMARY_WEIGHTS)]


@pytest.mark.parametrize(
    ("kind", "said"),
    [
        ("saturated", "saturated"),
        ("dark", "barely brighter"),
        ("moved", "disagree"),
        ("unseen", "no projector pixel"),
    ],
)
def test_bad_captures_are_refused_with_what_to_redo(kind: str, said: str) -> None:
    k0, kw, kb, kg, kr = _flat_captures(150.0)
    if kind == "saturated":
        kw = np.where(np.arange(SHAPE[1]) < 10, 255.0, kw)
    elif kind == "dark":
        k0, kw, kb, kg, kr = _flat_captures(4.0, dark=30.0)
    elif kind == "moved":
        kr = kr * 0.4
    else:
        k0 = np.full(SHAPE, np.nan)
    with pytest.raises(CalibrationError, match=said):
        measure(k0, kw, [kb, kg, kr])


def test_a_surface_too_dark_to_lift_is_refused() -> None:
    """Half the picture reflects 5 % of the rest: lifting it would keep under a quarter
    of the brightness; the compensation is refused (the geometric gain stays)."""
    k0, kw, kb, kg, kr = _flat_captures(150.0)
    dim = np.where(np.arange(SHAPE[1]) < SHAPE[1] // 2, 0.05, 1.0)
    r = measure(k0, kw * dim, [kb * dim, kg * dim, kr * dim])
    with pytest.raises(CalibrationError, match="too dark to compensate"):
        plan(r)


def _albedo(kind: str, shape: tuple[int, int]) -> np.ndarray:
    """Textures of contrast 0.5 (bricks with mortar, fine noise, stripes) with tints."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    rng = np.random.default_rng(3)
    if kind == "bricks":
        t = (((y // 12) % 2 == 0) ^ ((x // 24) % 2 == 0)) * 0.3 + ((y % 12) < 2) * 0.7
        tint = np.array([0.65, 0.8, 0.95])
    elif kind == "noise":
        t = cv2.GaussianBlur(rng.uniform(0, 1, (h, w)), (0, 0), 3.0)
        t = (t - t.min()) / np.ptp(t)
        tint = np.array([0.9, 0.95, 0.8])
    else:
        t = 0.5 + 0.5 * np.sin(x / 9.0)
        tint = np.array([1.0, 0.85, 0.85])
    return np.asarray(tint * (1.0 - 0.5 * np.clip(t, 0, 1))[..., None], np.float32)


@pytest.mark.parametrize(
    ("surface", "kind", "ambient"),
    [("corner", "bricks", 0.1), ("sphere-concave", "noise", 0.05), ("plane", "stripes", 0.0)],
)
def test_textured_tinted_surface_looks_like_white_end_to_end(
    surface: str, kind: str, ambient: float
) -> None:
    """Simulated captures -> measured response -> per-frame gain in 8 bits -> what a
    viewer sees, judged against the content on a uniform white surface: the Done-when
    figures (PSNR >= 25 dB, SSIM >= 0.85) compensated, uncompensated well below. The
    viewer's light is the test's own model (L = albedo (E p + ambient), E of the
    frontal plane's cos / d^2 from the projector's rays only for ``plane``)."""
    proj = Projector.default(320, 200)
    surf = simulate_surface(surface, proj)
    e = scaled_irradiance(surf)
    if surface == "plane":  # E ~ cos / d^2 = z / |X|^3 on z = const, independently
        rays = np.linalg.inv(proj.K) @ np.stack(
            [*np.meshgrid(np.arange(320.0), np.arange(200.0)), np.ones((200, 320))]
        ).reshape(3, -1)
        own = (1.0 / np.linalg.norm(rays, axis=0) ** 3).reshape(200, 320)
        own /= np.percentile(own, 99.9)
        assert np.allclose(e, np.minimum(own, 1.0), rtol=1e-3)
    albedo = _albedo(kind, e.shape)
    caps = simulated_captures(albedo, e, ambient, np.random.default_rng(1))
    response = measure(caps["black"], caps["white"], [caps["blue"], caps["green"], caps["red"]])
    gain = colour_gain(response, plan(response, lift=False), (320, 200))
    content = poster((320, 200))
    lin = (np.arange(256) / 255.0) ** 2.2
    where = e > 0
    before = albedo * (lin[content] * e[..., None] + ambient)
    after = albedo * (lin[apply_gain(content, gain)] * e[..., None] + ambient)
    psnr0, ssim0 = scores(before, content, where)
    psnr1, ssim1 = scores(after, content, where)
    assert psnr1 >= 25.0 and ssim1 >= 0.85, (psnr0, ssim0, psnr1, ssim1)
    assert psnr1 > psnr0 + 3.0


def test_a_refused_surface_keeps_the_geometric_gain() -> None:
    """``adaproj simulate``'s measured path on a surface too dark to lift (a third of
    it reflects 3 %): the reason is said and the gain is the geometric one (from the
    surface's shape: one channel, never brighter)."""
    from adaproj_edge.commands.simulate import SurfaceColour, measured_gain

    surf = simulate_surface("corner", Projector.default(320, 200))
    albedo = np.ones((200, 320, 3), np.float32)
    albedo[:, :110] = 0.03
    notes: list[str] = []
    gain = measured_gain(surf, SurfaceColour(albedo, 0.02), notes)
    assert len(notes) == 1 and "not compensated" in notes[0] and "too dark" in notes[0]
    assert gain.light.ndim == 2 and float(gain.light.max()) <= 1.0
