"""Inputs shared by the warp commands: surfaces by name or file, content maps."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.content.contentmap import ContentMap, combine_maps, content_map_for
from adaproj_edge.content.mask import load_mask
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import SURFACES, simulate_surface
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.warpmap import Grid

log = logging.getLogger(__name__)


def load_surface(spec: str) -> Surface:
    """A Surface file, or the name of a built-in analytic surface."""
    if spec in SURFACES and not Path(spec).exists():
        return simulate_surface(spec)
    return Surface.load(spec)


def content_map(
    image: NDArray[np.uint8],
    mask: NDArray[np.floating] | None,
    given: NDArray[np.floating] | None,
    threshold: float,
    *,
    saliency: bool = True,
    model: SaliencyModel | None = None,
) -> ContentMap | None:
    """C for ``image`` from a user ``mask`` and a ``given`` content map (both (h, w) in
    [0, 1] at the content size, e.g. from :func:`load_mask`): the given map max the mask;
    without one, the saliency model max the mask; with ``saliency`` off, the mask alone
    (None without one: uniform)."""
    h, w = image.shape[:2]
    if given is not None:
        return ContentMap(
            combine_maps([given] + ([mask] if mask is not None else [])), (w, h), threshold
        )
    if saliency:
        log.debug("computing the saliency map")
        return content_map_for(image, mask, model, threshold=threshold)
    if mask is not None:
        return ContentMap(np.asarray(mask, np.float32), (w, h), threshold)
    return None


def load_maps(
    image: NDArray[np.uint8], mask_path: Path | None, map_path: Path | None
) -> tuple[NDArray[np.float32] | None, NDArray[np.float32] | None]:
    """The user mask and a content-map file, read and fitted to the content."""
    h, w = image.shape[:2]
    mask = None if mask_path is None else load_mask(mask_path, (w, h))
    given = None if map_path is None else load_mask(map_path, (w, h))
    return mask, given


def grid_arg(text: str) -> Grid:
    """argparse type for ``--grid 20x20``."""
    try:
        return Grid.parse(text)
    except InputError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def vector_arg(text: str) -> tuple[float, float, float]:
    """argparse type for ``--viewer X,Y,Z`` (metres, frame P)."""
    try:
        x, y, z = (float(t) for t in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in metres, got {text!r}") from None
    return x, y, z
