"""Gray-code patterns and their decoding, against OpenCV's own decoder and against
captures made from a known camera -> projector mapping."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import InputError
from adaproj_edge.procam.graycode import PatternSet, decode, gray_code_pattern
from adaproj_edge.procam.pairs import edge_samples


def test_patterns_are_opencvs() -> None:
    ps = PatternSet(64, 40)
    ok, ref = gray_code_pattern(64, 40).generate()
    assert ok and len(ps) == len(ref) + 2 == 2 + 2 * (6 + 6)
    for i, img in enumerate(ref):
        assert np.array_equal(ps.gray(i + 2), img)
    assert ps.frame(0).max() == 0 and ps.frame(1).min() == 255
    assert ps.frame(5).shape == (40, 64, 3)
    names = [p.name for p in ps.patterns]
    assert names[:4] == ["black", "white", "x0", "x0-inv"] and names[-1] == "y5-inv"


def test_decode_of_the_patterns_themselves_matches_opencv() -> None:
    """A camera that sees the projector pixel for pixel: every pixel decodes, and to
    what OpenCV's getProjPixel says."""
    w, h = 96, 50
    ps = PatternSet(w, h)
    images = [ps.gray(i) for i in range(len(ps))]
    dec = decode(images, ps)
    assert dec.cell_x == dec.cell_y == 1 and dec.valid.all()
    gc = gray_code_pattern(w, h)
    rng = np.random.default_rng(0)
    for x, y in zip(rng.integers(0, w, 40), rng.integers(0, h, 40), strict=True):
        err, (px, py) = gc.getProjPixel(images[2:], int(x), int(y))
        assert not err and (dec.code_x[y, x], dec.code_y[y, x]) == (px, py) == (x, y)


def _camera_view(ps: PatternSet, scale: float, shift: tuple[float, float], size: tuple[int, int]):
    """Captures of a camera whose pixel (u, v) sees projector point
    (scale * u + shift), blurred over its footprint; and that map."""
    w, h = size
    u, v = np.meshgrid(np.arange(w * 4) / 4 - 0.375, np.arange(h * 4) / 4 - 0.375)
    mx = (scale * u + shift[0]).astype(np.float32)
    my = (scale * v + shift[1]).astype(np.float32)
    imgs = []
    for i in range(len(ps)):
        light = ps.gray(i).astype(np.float32) * 0.7 + 20
        fine = cv2.remap(light, mx, my, cv2.INTER_LINEAR, borderValue=0)
        imgs.append(np.clip(cv2.resize(fine, (w, h), interpolation=cv2.INTER_AREA), 0, 255))
    uu, vv = np.meshgrid(np.arange(w), np.arange(h))
    return (
        [np.rint(im).astype(np.uint8) for im in imgs],
        scale * uu + shift[0],
        scale * vv + shift[1],
    )


def test_decode_stops_at_the_finest_resolved_bit() -> None:
    """A camera pixel 3.5 projector pixels wide: the finest stripes blur to grey, the
    decode keeps the bits above them, and each pixel's cell holds its true point."""
    ps = PatternSet(640, 400)
    imgs, tx, ty = _camera_view(ps, 3.5, (10.3, 7.9), (160, 100))
    dec = decode(imgs, ps)
    for cell, contrast, bits in (
        (dec.cell_x, dec.contrast_x, ps.bits_x),
        (dec.cell_y, dec.contrast_y, ps.bits_y),
    ):
        # decoding stopped at the first bit under the contrast limit, which was tried
        assert contrast[-1] < 0.4 and min(contrast[:-1]) >= 0.4 and len(contrast) <= bits
        assert cell == 2 ** (bits - len(contrast) + 1) >= 2
    ok = dec.valid
    assert ok.mean() > 0.9
    in_x = np.abs(dec.x - tx)[ok] <= dec.cell_x / 2 + 1.0
    in_y = np.abs(dec.y - ty)[ok] <= dec.cell_y / 2 + 1.0
    assert in_x.mean() > 0.97 and in_y.mean() > 0.97
    # edges between cells, to a fraction of a projector pixel
    u, _, val = edge_samples(dec.code_x, dec.cell_x, dec.diff_x)
    truth = 3.5 * u + 10.3
    assert len(u) > 1000 and np.median(np.abs(val - truth)) < 0.4


def test_dark_and_saturated_captures_are_told() -> None:
    ps = PatternSet(64, 40)
    dark = [np.full((40, 64), 3, np.uint8)] * len(ps)
    d = decode(dark, ps)
    assert d.lit_fraction == 0 and d.decoded_fraction == 0 and d.signal == 0
    bright = [np.maximum(ps.gray(i), 200).astype(np.uint8) for i in range(len(ps))]
    bright[0] = np.full((40, 64), 200, np.uint8)
    b = decode(bright, ps)
    assert b.saturated_fraction == 1.0 and b.ambient_ratio == pytest.approx(200 / 255, abs=0.01)


def test_bad_capture_lists() -> None:
    ps = PatternSet(64, 40)
    with pytest.raises(InputError, match="captures for"):
        decode([ps.gray(0)], ps)
    with pytest.raises(InputError, match="grey uint8"):
        decode([ps.gray(i).astype(np.float32) for i in range(len(ps))], ps)  # type: ignore[misc]


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 40), st.integers(2, 30))
def test_decode_of_any_images_is_well_formed(seed: int, w: int, h: int) -> None:
    """Whatever the camera sends, codes stay inside the projector frame or are -1."""
    ps = PatternSet(50, 20)
    rng = np.random.default_rng(seed)
    imgs = [rng.integers(0, 256, (h, w), dtype=np.uint8) for _ in range(len(ps))]
    d = decode(imgs, ps)
    for code, cell, size in ((d.code_x, d.cell_x, 50), (d.code_y, d.cell_y, 20)):
        assert code.shape == (h, w)
        assert np.all((code == -1) | ((code >= 0) & (code * cell < size)))
    assert 0 <= d.saturated_fraction <= 1 and d.diff_x.shape[1:] == (h, w)
