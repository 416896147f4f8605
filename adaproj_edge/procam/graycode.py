"""Gray-code structured light: the patterns the projector shows, and their decoding.

The patterns are OpenCV contrib's ``cv2.structured_light.GrayCodePattern`` for the
projector's resolution: for each bit of the column code (most significant first),
then of the row code, a pattern and its inverse; we show all-black and all-white
first (shadow masks: which camera pixels the projector lights at all).

Decoding compares each pattern with its inverse per camera pixel, as OpenCV's
``getProjPixel`` does, but for the whole image at once and only down to the finest
bit the camera resolves: the depth-aligned camera of a depth sensor sees a
projector pixel smaller than its own pixels, so the finest stripes (2-4 projector
pixels) blur to grey. A bit counts as resolved when the median contrast
``|pattern - inverse| / (white - black)`` over the lit pixels reaches
``bit_contrast``; every pixel is then decoded to a *cell* of ``2^k`` projector
pixels (the bits above the first unresolved one), whose centre is its projector
coordinate. A Gray code changes one bit between neighbouring cells, so a bit read
wrongly at a stripe edge moves the pixel to the neighbouring cell only; positions
finer than a cell come from the cells' edges, where the bit that changes crosses
zero (:func:`adaproj_edge.procam.pairs.edge_samples`).

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray, Image
from adaproj_edge.errors import InputError


@dataclass(frozen=True)
class Pattern:
    """One projected pattern: ``kind`` is ``"black"``, ``"white"`` or ``"bit"``; a bit
    pattern has an ``axis`` (``"x"``: columns, ``"y"``: rows), a ``bit`` (0 = most
    significant) and whether it is the ``inverse``."""

    index: int
    kind: str
    axis: str = ""
    bit: int = -1
    inverse: bool = False

    @property
    def name(self) -> str:
        if self.kind != "bit":
            return self.kind
        return f"{self.axis}{self.bit}{'-inv' if self.inverse else ''}"


class PatternSet:
    """The patterns of one projector resolution (``width`` x ``height``).

    ``frame(i)`` is pattern ``i`` as a BGR frame for the display; frames are built
    on demand from one profile per pattern (the patterns are stripes).
    """

    def __init__(self, width: int, height: int) -> None:
        if width < 2 or height < 2:
            raise InputError(f"pattern size {width}x{height} is too small")
        self.width, self.height = int(width), int(height)
        gc = gray_code_pattern(self.width, self.height)
        ok, images = gc.generate()
        if not ok:
            raise InputError(f"OpenCV could not make Gray-code patterns for {width}x{height}")
        self.bits_x = int(np.ceil(np.log2(self.width)))
        self.bits_y = int(np.ceil(np.log2(self.height)))
        patterns = [Pattern(0, "black"), Pattern(1, "white")]
        profiles: list[NDArray[np.uint8]] = [
            np.zeros(self.width, np.uint8),
            np.full(self.width, 255, np.uint8),
        ]
        for i, img in enumerate(images):
            axis = "x" if i < 2 * self.bits_x else "y"
            bit = (i if axis == "x" else i - 2 * self.bits_x) // 2
            patterns.append(Pattern(len(patterns), "bit", axis, bit, i % 2 == 1))
            pixels: NDArray[np.uint8] = np.asarray(img, np.uint8)
            profiles.append(pixels[0].copy() if axis == "x" else pixels[:, 0].copy())
        self.patterns: tuple[Pattern, ...] = tuple(patterns)
        self._profiles = profiles

    def __len__(self) -> int:
        return len(self.patterns)

    def profile(self, index: int) -> NDArray[np.uint8]:
        """The pattern's values along its axis: (width,) for columns, black and white,
        (height,) for rows."""
        return self._profiles[index]

    def gray(self, index: int) -> Image:
        """Pattern ``index`` as a (height, width) uint8 image."""
        p = self.patterns[index]
        prof = self._profiles[index]
        if p.axis == "y":
            return np.ascontiguousarray(np.broadcast_to(prof[:, None], (self.height, self.width)))
        return np.ascontiguousarray(np.broadcast_to(prof[None, :], (self.height, self.width)))

    def frame(self, index: int) -> Image:
        """Pattern ``index`` as a (height, width, 3) BGR uint8 frame (a read-only view:
        one grey value per pixel, broadcast to the three channels)."""
        return np.broadcast_to(self.gray(index)[..., None], (self.height, self.width, 3))

    def index_of(self, axis: str, bit: int, inverse: bool) -> int:
        """The index of a bit pattern."""
        first = 2 if axis == "x" else 2 + 2 * self.bits_x
        return first + 2 * bit + int(inverse)


def gray_code_pattern(width: int, height: int) -> cv2.structured_light.GrayCodePattern:
    """OpenCV's Gray-code pattern generator, with a clear error if the installed OpenCV
    lacks the contrib ``structured_light`` module."""
    module = getattr(cv2, "structured_light", None)
    if module is None or not hasattr(module, "GrayCodePattern"):
        raise InputError(
            "this OpenCV has no cv2.structured_light.GrayCodePattern: install "
            "opencv-contrib-python-headless (not opencv-python)"
        )
    pattern: cv2.structured_light.GrayCodePattern = module.GrayCodePattern.create(
        int(width), int(height)
    )
    return pattern


@dataclass(frozen=True)
class DecodeSettings:
    """Thresholds of :func:`decode` (grey levels and fractions of white - black)."""

    min_lit: float = 10.0
    lit_fraction_of_max: float = 0.1
    bit_contrast: float = 0.4
    saturated: int = 250


@dataclass(frozen=True)
class Decoded:
    """One pose's captures decoded.

    Attributes
    ----------
    code_x, code_y : (h, w) int32
        The cell each camera pixel decodes to along x and y, -1 where none.
    cell_x, cell_y : int
        Cell size in projector pixels along x and y (``2^k``): cell ``c`` holds
        projector pixels ``c * cell`` to ``c * cell + cell - 1``.
    diff_x, diff_y : (bits, h, w) float32
        ``(pattern - inverse) / (white - black)`` of each bit used (most significant
        first): its sign is the bit, its zero crossings the stripe edges.
    lit : (h, w) bool
        Pixels the projector lights (white - black above the thresholds).
    contrast_x, contrast_y : tuple of float
        Median contrast of each bit (most significant first) over the lit pixels.
    saturated_fraction : float
        Fraction of the lit pixels that are saturated in the white capture.
    ambient_ratio : float
        Median black / white over the lit pixels (ambient light).
    signal : float
        Median white - black over the lit pixels, in grey levels.
    """

    code_x: NDArray[np.int32]
    code_y: NDArray[np.int32]
    cell_x: int
    cell_y: int
    diff_x: NDArray[np.float32]
    diff_y: NDArray[np.float32]
    lit: BoolArray
    contrast_x: tuple[float, ...]
    contrast_y: tuple[float, ...]
    saturated_fraction: float
    ambient_ratio: float
    signal: float

    @cached_property
    def valid(self) -> BoolArray:
        """(h, w): decoded along both axes."""
        return np.asarray((self.code_x >= 0) & (self.code_y >= 0))

    @property
    def x(self) -> FloatArray:
        """(h, w) projector x of each pixel's cell centre, NaN where not decoded."""
        return _centres(self.code_x, self.cell_x)

    @property
    def y(self) -> FloatArray:
        """(h, w) projector y of each pixel's cell centre, NaN where not decoded."""
        return _centres(self.code_y, self.cell_y)

    @property
    def lit_fraction(self) -> float:
        return float(np.mean(self.lit))

    @property
    def decoded_fraction(self) -> float:
        return float(np.mean(self.valid))


def _centres(code: NDArray[np.int32], cell: int) -> FloatArray:
    return np.where(code >= 0, code * float(cell) + (cell - 1) / 2.0, np.nan)


def _axis(
    images: Sequence[Image],
    patterns: PatternSet,
    axis: str,
    lit: BoolArray,
    span: NDArray[np.float32],
    settings: DecodeSettings,
) -> tuple[NDArray[np.int32], int, NDArray[np.float32], tuple[float, ...]]:
    """The cell of each pixel along ``axis`` (-1: none), the cell size, the normalised
    differences of the bits used, and the median contrast of each bit tried."""
    n_bits = patterns.bits_x if axis == "x" else patterns.bits_y
    size = patterns.width if axis == "x" else patterns.height
    diffs: list[NDArray[np.float32]] = []
    contrasts: list[float] = []
    n_lit = int(lit.sum())
    for b in range(n_bits):
        pos = images[patterns.index_of(axis, b, False)].astype(np.float32)
        neg = images[patterns.index_of(axis, b, True)].astype(np.float32)
        diff = (pos - neg) / span
        c = float(np.median(np.abs(diff[lit]))) if n_lit else 0.0
        contrasts.append(round(c, 4))
        if c < settings.bit_contrast:
            break
        diffs.append(diff)
    # the bits that count: every one from the most significant down to the first
    # unresolved one
    kept = len(diffs)
    shape = lit.shape
    if kept == 0:
        return (
            np.full(shape, -1, np.int32),
            1 << n_bits,
            np.zeros((0, *shape), np.float32),
            (tuple(contrasts)),
        )
    code = np.zeros(shape, np.int32)
    binary = np.zeros(shape, np.bool_)
    for d in diffs:
        binary = binary ^ (d > 0)  # Gray -> binary: running XOR from the top bit
        code = (code << 1) | binary
    cell = 1 << (n_bits - kept)
    code = np.where(lit & (code * cell < size), code, -1).astype(np.int32)
    return code, cell, np.stack(diffs), tuple(contrasts)


def decode(
    images: Sequence[Image], patterns: PatternSet, settings: DecodeSettings | None = None
) -> Decoded:
    """Decode one pose's captures.

    Parameters
    ----------
    images : sequence of (h, w) uint8
        One grey capture per pattern of ``patterns``, in pattern order.
    patterns : PatternSet
    settings : DecodeSettings, optional

    Returns
    -------
    Decoded
    """
    s = settings or DecodeSettings()
    if len(images) != len(patterns):
        raise InputError(f"{len(images)} captures for {len(patterns)} patterns")
    shape = images[0].shape
    if len(shape) != 2 or any(im.shape != shape or im.dtype != np.uint8 for im in images):
        raise InputError("captures must be grey uint8 images of one size")
    black = images[0].astype(np.float32)
    white = images[1].astype(np.float32)
    span = white - black
    top = float(np.percentile(span, 99.5)) if span.size else 0.0
    lit = np.asarray(span >= max(s.min_lit, s.lit_fraction_of_max * top))
    safe_span = np.maximum(span, 1.0)
    x, cell_x, dx, cx = _axis(images, patterns, "x", lit, safe_span, s)
    y, cell_y, dy, cy = _axis(images, patterns, "y", lit, safe_span, s)
    n_lit = int(lit.sum())
    if n_lit:
        saturated = float(np.mean(images[1][lit] >= s.saturated))
        ambient = float(np.median(black[lit] / np.maximum(white[lit], 1.0)))
        signal = float(np.median(span[lit]))
    else:
        saturated, ambient, signal = 0.0, 1.0, 0.0
    return Decoded(x, y, cell_x, cell_y, dx, dy, lit, cx, cy, saturated, ambient, signal)
