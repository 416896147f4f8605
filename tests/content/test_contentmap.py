"""Masks, the combined content map, the per-item cache."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.ndimage
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.content.cache import ContentMapper
from adaproj_edge.content.contentmap import (
    DEFAULT_THRESHOLD,
    ContentMap,
    coarse_size,
    combine,
    content_map_for,
)
from adaproj_edge.content.mask import decode_mask, load_mask
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.errors import ImageError, InputError, MaskError
from tests.content.displays import colour_popout


def _png(img: np.ndarray) -> bytes:
    ok, enc = cv2.imencode(".png", img)
    assert ok
    return enc.tobytes()


def _mask_png(w: int, h: int, box: tuple[int, int, int, int]) -> bytes:
    m = np.zeros((h, w), np.uint8)
    x0, y0, x1, y1 = box
    m[y0:y1, x0:x1] = 255
    return _png(m)


def test_coarse_size_follows_the_grid_and_the_aspect() -> None:
    assert coarse_size((1280, 800)) == (80, 50)
    assert coarse_size((800, 1280)) == (50, 80)
    assert coarse_size((60, 40)) == (60, 40)  # never larger than the content
    assert coarse_size((4000, 10)) == (80, 2)
    assert coarse_size((1280, 800), grid=(40, 40)) == (160, 100)


def test_mask_of_any_size_is_resized_to_the_content() -> None:
    m = decode_mask(_mask_png(64, 40, (32, 0, 64, 40)), (1280, 800))
    assert m.shape == (800, 1280) and m.dtype == np.float32
    assert m[:, :600].max() == 0.0 and m[:, 700:].min() == 1.0


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"", "empty"),
        (b"\x89PNG\r\n\x1a\n garbage", "not a readable image"),
        (_mask_png(100, 100, (0, 0, 50, 50)), "aspect ratio"),
    ],
)
def test_bad_masks_are_rejected_clearly(data: bytes, message: str) -> None:
    with pytest.raises(MaskError, match=message) as info:
        decode_mask(data, (1280, 800))
    assert isinstance(info.value, ImageError)


def test_load_mask_names_the_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MaskError, match=r"not found: .*nope\.png"):
        load_mask(tmp_path / "nope.png", (100, 100))


def test_combine_is_the_pixelwise_max() -> None:
    s = np.array([[0.2, 0.9], [0.5, np.nan]], np.float32)
    m = np.array([[0.7, 0.1], [0.5, 1.0]], np.float32)
    out = combine((2, 2), s, m)
    assert out is not None
    np.testing.assert_allclose(out, [[0.7, 0.9], [0.5, 1.0]])
    assert combine((2, 2)) is None
    with pytest.raises(InputError, match="does not match"):
        combine((3, 2), s)


def test_content_map_weights_follow_eq5() -> None:
    values = np.zeros((10, 16), np.float32)
    values[:, 8:] = 1.0
    cmap = ContentMap(values, (160, 100))
    xy = np.array([[10.0, 50.0], [150.0, 50.0], [-20.0, 50.0], [150.0, 500.0]])
    np.testing.assert_array_equal(cmap.weights(xy), [0.0, 1.0, 0.0, 0.0])
    assert cmap.threshold == DEFAULT_THRESHOLD
    assert cmap.full_size().shape == (100, 160)
    assert cmap.salient().mean() == 0.5


def test_mask_raises_the_map_where_the_user_marked(model: SaliencyModel) -> None:
    image, _, _ = colour_popout(5)
    mask = decode_mask(_mask_png(128, 80, (0, 60, 20, 80)), (1280, 800))
    plain = content_map_for(image, model=model)
    masked = content_map_for(image, mask, model=model)
    assert np.all(masked.values >= plain.values)
    corner = np.array([[60.0, 740.0]])
    assert plain.weights(corner)[0] == 0.0 and masked.weights(corner)[0] == 1.0
    assert masked.values.shape == (50, 80)


def test_cache_recomputes_only_what_changed(model: SaliencyModel) -> None:
    mapper = ContentMapper(model)
    a, _, _ = colour_popout(5)
    b, _, _ = colour_popout(10)
    mapper.set_content("a", a)
    mapper.set_content("a", a.copy())
    assert mapper.stats.saliency_runs == 1
    first = mapper.content_map("a")
    mapper.set_mask("a", _mask_png(128, 80, (0, 0, 64, 80)))
    mapper.set_mask("a", _mask_png(128, 80, (0, 0, 64, 80)))
    assert (mapper.stats.saliency_runs, mapper.stats.mask_decodes) == (1, 1)
    masked = mapper.content_map("a")
    assert masked.values[:, :30].min() == 1.0 and first.values[:, :30].min() < 1.0
    mapper.set_content("a", b)  # new content: the model runs, the mask is re-fitted
    assert (mapper.stats.saliency_runs, mapper.stats.mask_decodes) == (2, 2)
    assert mapper.content_map("a").values[:, :30].min() == 1.0
    mapper.set_mask("a", None)
    np.testing.assert_array_equal(
        mapper.content_map("a").values, content_map_for(b, model=model).values
    )


def test_a_bad_mask_leaves_the_content_usable(model: SaliencyModel) -> None:
    mapper = ContentMapper(model)
    image, _, _ = colour_popout(5)
    mapper.set_content("x", image)
    before = mapper.content_map("x").values
    with pytest.raises(MaskError, match="aspect ratio"):
        mapper.set_mask("x", _mask_png(50, 50, (0, 0, 10, 10)))
    with pytest.raises(MaskError, match="not a readable image"):
        mapper.set_mask("x", b"\x89PNG\r\n\x1a\n broken")
    np.testing.assert_array_equal(mapper.content_map("x").values, before)
    with pytest.raises(InputError, match="no content named"):
        mapper.content_map("y")
    with pytest.raises(InputError, match="no content named"):
        mapper.set_mask("y", None)


def test_cache_forgets_the_least_recently_used(model: SaliencyModel) -> None:
    mapper = ContentMapper(model, max_items=2)
    img = np.zeros((20, 30, 3), np.uint8)
    for name in ("a", "b", "c"):
        mapper.set_content(name, img)
    assert "a" not in mapper and "b" in mapper and "c" in mapper
    mapper.forget("b")
    assert "b" not in mapper


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    size=st.tuples(st.integers(2, 400), st.integers(2, 400)),
    grid=st.integers(2, 30),
)
def test_weights_threshold_the_sampled_map(seed: int, size: tuple[int, int], grid: int) -> None:
    rng = np.random.default_rng(seed)
    w, h = size
    cw, ch = coarse_size(size, (grid, grid))
    cmap = ContentMap(rng.random((ch, cw)).astype(np.float32), size)
    xy = rng.uniform(-0.2, 1.2, (200, 2)) * [w, h]
    s = cmap.sample(xy)
    assert s.dtype == np.float32 and s.min() >= 0.0 and s.max() <= 1.0
    np.testing.assert_array_equal(cmap.weights(xy), (s >= cmap.threshold).astype(np.float32))
    outside = (xy[:, 0] < -0.5) | (xy[:, 0] > w - 0.5) | (xy[:, 1] < -0.5) | (xy[:, 1] > h - 0.5)
    assert np.all(s[outside] == 0.0)


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    shape=st.tuples(st.integers(1, 60), st.integers(1, 60)),
    size=st.tuples(st.integers(2, 700), st.integers(2, 700)),
)
def test_sample_is_scipys_bilinear_with_edges_held(
    seed: int, shape: tuple[int, int], size: tuple[int, int]
) -> None:
    """The written-out sampler against scipy's (order 1, edge values held), on any map
    shape (one-sample axes included), at random, integer and unknown positions."""
    rng = np.random.default_rng(seed)
    w, h = size
    values = rng.random(shape).astype(np.float32)
    xy = rng.uniform(-0.3, 1.3, (300, 2)) * [w, h]
    xy[::5] = np.round(xy[::5])
    xy[3] = np.nan
    got = ContentMap(values, size).sample(xy)
    pts = np.nan_to_num(xy, nan=-1.0)
    mh, mw = shape
    coords = [(pts[:, 1] + 0.5) * (mh / h) - 0.5, (pts[:, 0] + 0.5) * (mw / w) - 0.5]
    ref = scipy.ndimage.map_coordinates(values, coords, output=np.float64, order=1, mode="nearest")
    inside = (pts[:, 0] >= -0.5) & (pts[:, 0] <= w - 0.5)
    inside &= (pts[:, 1] >= -0.5) & (pts[:, 1] <= h - 0.5)
    np.testing.assert_allclose(got, np.where(inside, ref, 0.0), rtol=0, atol=1e-6)
