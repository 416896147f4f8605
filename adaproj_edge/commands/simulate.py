"""``adaproj simulate``: see what a viewer off to the side sees, plain vs corrected."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
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

PRIMARIES = ("blue", "green", "red")

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from adaproj_edge.content.contentmap import ContentMap
    from adaproj_edge.geometry.surface import Surface
    from adaproj_edge.render.photometry import GainMap
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
    p.add_argument(
        "--albedo",
        type=Path,
        help="PNG of the surface's colour (reflectance) as the projector sees it, resized to "
        "the frame: the projections are shown as a viewer sees them on it; with --compensate "
        "its colour is measured from simulated captures and compensated",
    )
    p.add_argument(
        "--ambient",
        type=ambient_arg,
        default=0.0,
        help="the room's light, a fraction of the projector's white (e.g. 0.05; "
        "default %(default)s)",
    )
    p.add_argument("--out", type=Path, required=True, help="picture to write (.png or .jpg)")
    p.set_defaults(run=run)


def ambient_arg(text: str) -> float:
    """Parse ``--ambient A`` (the argparse type): a finite fraction in [0, 1]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text!r}") from None
    if not 0.0 <= value <= 1.0:  # NaN fails too
        raise argparse.ArgumentTypeError(f"the ambient light must be in [0, 1], got {text!r}")
    return value


@dataclass(frozen=True)
class SurfaceColour:
    """The simulated surface's reflectance ``albedo`` (H, W, 3) in [0, 1] (blue,
    green, red; None: white) and the room's light ``ambient`` (a fraction of the
    projector's white)."""

    albedo: NDArray[np.float32] | None = None
    ambient: float = 0.0


def measured_gain(surface: Surface, colour: SurfaceColour, notes: list[str]) -> GainMap:
    """The compensation of ``colour`` measured as on the device, from the simulated
    calibration camera's captures (:mod:`adaproj_edge.render.reflectance`); when the
    captures or the surface are refused, the gain from the surface's shape alone and
    the reason in ``notes``."""
    import numpy as np

    from adaproj_edge.errors import CalibrationError
    from adaproj_edge.render.photometry import gain_map
    from adaproj_edge.render.reflectance import colour_gain, measure, plan
    from adaproj_edge.render.surface_light import scaled_irradiance, simulated_captures

    p = surface.projector
    e = scaled_irradiance(surface)
    albedo = colour.albedo if colour.albedo is not None else np.ones((*e.shape, 3), np.float32)
    caps = simulated_captures(albedo, e, colour.ambient, np.random.default_rng(0))
    try:
        response = measure(caps["black"], caps["white"], [caps[c] for c in PRIMARIES])
        comp = plan(response, lift=False)
    except CalibrationError as err:
        notes.append(f"surface colour not compensated: {err}")
        return gain_map(surface)
    notes.append(
        f"surface colour compensated: {comp.kept:.0%} of the brightness kept, "
        f"{comp.clipped:.1%} of the picture short of white"
    )
    return colour_gain(response, comp, (p.width, p.height))


def simulate(
    surface: Surface,
    image: NDArray[np.uint8],
    cmap: ContentMap | None,
    settings: WarpSettings,
    eye: tuple[float, float, float],
    name: str = "the surface",
    compensate: bool = False,
    colour: SurfaceColour | None = None,
    notes: list[str] | None = None,
) -> tuple[NDArray[np.uint8], Projection, Projection]:
    """The picture input | standard | corrected, titled with the surface's ``name`` and
    where the viewer stands, and the two projections. With ``compensate`` every
    projection is shown as bright as the projector's light makes it, and the corrected
    frame with the brightness gain (:mod:`adaproj_edge.render.photometry`) is added.
    With ``colour`` every projection is shown as a viewer sees it on that surface in
    that room (:mod:`adaproj_edge.render.surface_light`), and the compensation is
    measured (:func:`measured_gain`; what it did is added to ``notes``)."""
    import numpy as np

    from adaproj_edge.render.photometry import apply_gain, gain_map
    from adaproj_edge.render.project import project
    from adaproj_edge.render.sheet import row, titled
    from adaproj_edge.render.surface_light import encode, scaled_irradiance, seen_light
    from adaproj_edge.render.viewer import lit_frame, view, viewer_for
    from adaproj_edge.warp.engine import WarpSettings

    plain = project(surface, image, None, WarpSettings(mode="standard", grid=settings.grid))
    corrected = project(surface, image, cmap, settings)
    viewer = viewer_for(surface, eye)
    frames = [plain.frame, corrected.frame]
    labels = ["input", "standard projector", f"adaproj ({settings.mode})"]
    note = "grey: surface left dark"
    if compensate:
        if colour is None:
            gain = gain_map(surface, picture=np.isfinite(corrected.map_xy[..., 0]))
        else:
            gain = measured_gain(surface, colour, [] if notes is None else notes)
        frames = [*frames, apply_gain(corrected.frame, gain)]
        labels.append("adaproj, light evened out" + (", colour compensated" if colour else ""))
    if colour is not None:
        e = scaled_irradiance(surface)
        albedo = colour.albedo if colour.albedo is not None else np.ones((*e.shape, 3), np.float32)
        frames = [encode(seen_light(f, albedo, e, colour.ambient)) for f in frames]
        note += f"; as seen on the surface's colour, room light {colour.ambient:.0%}"
    elif compensate:
        frames = [lit_frame(surface, f) for f in frames]
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
    from adaproj_edge.render.surface_light import albedo_from_image
    from adaproj_edge.warp.engine import WarpSettings

    surface = load_surface(args.surface)
    colour = None
    if args.albedo is not None or args.ambient > 0:
        p = surface.projector
        albedo = None
        if args.albedo is not None:
            albedo = albedo_from_image(read_image(args.albedo), (p.width, p.height))
        colour = SurfaceColour(albedo, args.ambient)
    image = poster() if args.image is None else read_image(args.image)
    mask, given = load_maps(image, args.mask, args.content_map)
    if args.image is None and mask is None:
        mask = poster_mask((image.shape[1], image.shape[0]))
    cmap = content_map(image, mask, given, DEFAULT_THRESHOLD, saliency=args.mode == "content")
    settings = WarpSettings(mode=args.mode, grid=args.grid)
    name = Path(args.surface).name
    notes: list[str] = []
    picture, _, _ = simulate(
        surface, image, cmap, settings, args.viewer, name, args.compensate, colour, notes
    )
    for line in notes:
        print(line)
    write_image(args.out, picture)
    print(f"wrote {args.out}")
    return 0
