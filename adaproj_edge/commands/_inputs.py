"""Inputs shared by the warp commands: surfaces by name or file, content maps, and the
argparse types of their options.

Importing this module is cheap (numpy and the rest load inside the functions), so a
command's ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import logging
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING

from adaproj_edge.errors import InputError, SurfaceError

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from adaproj_edge.content.contentmap import ContentMap
    from adaproj_edge.content.model import SaliencyModel
    from adaproj_edge.geometry.surface import Surface
    from adaproj_edge.warp.warpmap import Grid

log = logging.getLogger(__name__)


def load_surface(spec: str) -> Surface:
    """A Surface file, or the name of a built-in analytic surface.

    Parameters
    ----------
    spec : str
        A path to a Surface ``.npz`` file, or a name from
        :data:`adaproj_edge.geometry.analytic.SURFACES` (a file of that name wins).

    Returns
    -------
    Surface
        The surface, (H, W, 3) points in frame P.

    Raises
    ------
    SurfaceError
        Neither a readable Surface file nor a built-in name (the names are listed).
    """
    from adaproj_edge.geometry.analytic import SURFACES, simulate_surface
    from adaproj_edge.geometry.surface import Surface

    path = Path(spec)
    if spec in SURFACES and not path.exists():
        return simulate_surface(spec)
    if not path.exists() and not path.is_symlink():
        raise SurfaceError(
            f"surface {spec!r} is neither a file nor a built-in surface ({', '.join(SURFACES)})"
        )
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
    import numpy as np

    from adaproj_edge.content.contentmap import ContentMap, combine_maps, content_map_for

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
    from adaproj_edge.content.mask import load_mask

    h, w = image.shape[:2]
    mask = None if mask_path is None else load_mask(mask_path, (w, h))
    given = None if map_path is None else load_mask(map_path, (w, h), kind="content map")
    return mask, given


def grid_arg(text: str) -> Grid:
    """Parse ``--grid 20x20`` (the argparse type): columns x rows of cells, enough of
    them for the warp's mesh (checked here, before any work)."""
    from adaproj_edge.warp.mesh import MIN_TRIANGLES
    from adaproj_edge.warp.warpmap import MAX_GRID, Grid

    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if m is not None:
        cols, rows = int(m[1]), int(m[2])
        if 2 * cols * rows < MIN_TRIANGLES:  # two triangles per cell
            raise argparse.ArgumentTypeError(
                f"grid {cols}x{rows} has {2 * cols * rows} triangles; the warp needs at "
                f"least {MIN_TRIANGLES} (e.g. 2x2)"
            )
        if max(cols, rows) > MAX_GRID:
            raise argparse.ArgumentTypeError(
                f"grid {cols}x{rows} is too fine: at most {MAX_GRID}x{MAX_GRID} cells"
            )
    try:
        return Grid.parse(text)
    except InputError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def vector_arg(text: str) -> tuple[float, float, float]:
    """Parse ``--viewer X,Y,Z`` (metres, frame P; the argparse type)."""
    try:
        x, y, z = (float(t) for t in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in metres, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise argparse.ArgumentTypeError(f"expected finite X,Y,Z in metres, got {text!r}")
    return x, y, z


def surface_names(text: str) -> list[str]:
    """Built-in surface names from a comma-separated list, all checked before any work.

    Raises
    ------
    InputError
        An empty list, or a name that is not built in (the built-in names are listed).
    """
    from adaproj_edge.geometry.analytic import SURFACES

    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise InputError(f"no surface named; choose from {', '.join(SURFACES)}")
    unknown = [n for n in names if n not in SURFACES]
    if unknown:
        raise InputError(
            f"unknown surface{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
            f"built-in surfaces: {', '.join(SURFACES)}"
        )
    return names
