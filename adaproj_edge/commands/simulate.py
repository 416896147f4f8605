"""``adaproj simulate``: see what a viewer off to the side sees, plain vs corrected."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from adaproj_edge.commands._inputs import (
    content_map,
    grid_arg,
    load_maps,
    load_surface,
    vector_arg,
)
from adaproj_edge.commands._outputs import check_image_file

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from adaproj_edge.content.contentmap import ContentMap
    from adaproj_edge.geometry.surface import Surface
    from adaproj_edge.render.project import Projection
    from adaproj_edge.warp.engine import WarpSettings


def register(sub: argparse._SubParsersAction[Any]) -> None:
    from adaproj_edge.render.viewer import DEFAULT_VIEWER
    from adaproj_edge.warp.engine import MODES
    from adaproj_edge.warp.warpmap import Grid

    p = sub.add_parser(
        "simulate",
        help="picture of the input, the plain and the corrected projection as a viewer sees them",
        description="Project an image (default: the built-in poster) onto a surface twice, "
        "plainly and corrected, and write one picture: the input, then both projections "
        "as a viewer at --viewer sees them (the standard projector's distortion next to "
        "adaproj's correction).",
    )
    p.add_argument(
        "--surface",
        required=True,
        help="Surface file (.npz) or a built-in surface name (see `adaproj surface --help`)",
    )
    p.add_argument("--image", type=Path, help="the content (default: the built-in poster)")
    p.add_argument("--mask", type=Path, help="user mask: PNG, white = important")
    p.add_argument("--content-map", type=Path, help="content map PNG (default: saliency)")
    p.add_argument("--mode", choices=MODES, default="content", help="the corrected projection")
    p.add_argument(
        "--grid", type=grid_arg, default=Grid(), help="cells, e.g. 20x20 (default %(default)s)"
    )
    p.add_argument(
        "--viewer",
        type=vector_arg,
        default=DEFAULT_VIEWER,
        help="viewer position X,Y,Z in metres, projector frame (default %(default)s)",
    )
    p.add_argument(
        "--compensate",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="even out the projector's light over the picture (a gain from the surface); "
        "the picture then shows the light's falloff on the surface (default: off)",
    )
    p.add_argument("--out", type=Path, required=True, help="picture to write (.png or .jpg)")
    p.set_defaults(run=run)


def simulate(
    surface: Surface,
    image: NDArray[np.uint8],
    cmap: ContentMap | None,
    settings: WarpSettings,
    eye: tuple[float, float, float],
    name: str = "the surface",
    compensate: bool = False,
) -> tuple[NDArray[np.uint8], Projection, Projection]:
    """The picture input | standard | corrected, titled with the surface's ``name`` and
    where the viewer stands, and the two projections. With ``compensate`` every
    projection is shown as bright as the projector's light makes it, and the corrected
    frame with the brightness gain (:mod:`adaproj_edge.render.photometry`) is added."""
    import numpy as np

    from adaproj_edge.render.photometry import apply_gain, gain_map
    from adaproj_edge.render.project import project
    from adaproj_edge.render.sheet import row, titled
    from adaproj_edge.render.viewer import lit_frame, view, viewer_for
    from adaproj_edge.warp.engine import WarpSettings

    plain = project(surface, image, None, WarpSettings(mode="standard", grid=settings.grid))
    corrected = project(surface, image, cmap, settings)
    viewer = viewer_for(surface, eye)
    frames = [plain.frame, corrected.frame]
    labels = ["input", "standard projector", f"adaproj ({settings.mode})"]
    note = "grey: surface left dark"
    if compensate:
        gain = gain_map(surface, picture=np.isfinite(corrected.map_xy[..., 0]))
        frames = [*frames, apply_gain(corrected.frame, gain)]
        frames = [lit_frame(surface, f) for f in frames]
        labels.append("adaproj, light evened out")
        note += "; brightness as the projector's light falls on the surface"
    picture = row([image, *(view(surface, f, viewer) for f in frames)], labels)
    x, y, z = eye
    title = (
        f"{name}, as a viewer at x {x:+.2f}, y {y:+.2f}, z {z:+.2f} m from the projector "
        f"sees it (x right, y down); {note}"
    )
    return titled(picture, [title]), plain, corrected


def run(args: argparse.Namespace) -> int:
    check_image_file(args.out, "picture")

    from adaproj_edge.content.builtin import poster, poster_mask
    from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD
    from adaproj_edge.fileio import read_image, write_image
    from adaproj_edge.warp.engine import WarpSettings

    surface = load_surface(args.surface)
    image = poster() if args.image is None else read_image(args.image)
    mask, given = load_maps(image, args.mask, args.content_map)
    if args.image is None and mask is None:
        mask = poster_mask((image.shape[1], image.shape[0]))
    cmap = content_map(image, mask, given, DEFAULT_THRESHOLD, saliency=args.mode == "content")
    settings = WarpSettings(mode=args.mode, grid=args.grid)
    name = Path(args.surface).name
    picture, _, _ = simulate(surface, image, cmap, settings, args.viewer, name, args.compensate)
    write_image(args.out, picture)
    print(f"wrote {args.out}")
    return 0
