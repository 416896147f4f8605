"""``adaproj saliency``: the content map of an image, as a file and as a picture."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from adaproj_edge.commands._outputs import check_image_file
from adaproj_edge.errors import InputError
from adaproj_edge.resources import default_model


def register(sub: argparse._SubParsersAction[Any]) -> None:
    from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD

    p = sub.add_parser(
        "saliency",
        help="compute an image's content map (saliency, faces, user mask)",
        description=(
            "Write the content map C = max(saliency, faces, mask) of IMAGE as a gray image "
            "of the image's size (white = important), optionally a picture of it over the "
            "image with the salient region outlined and the faces found drawn as ellipses."
        ),
    )
    p.add_argument("image", type=Path, help="the content (PNG or JPEG)")
    p.add_argument("--out", type=Path, required=True, help="where to write the map (.png)")
    p.add_argument("--mask", type=Path, help="user mask: PNG, white = important, any size")
    p.add_argument("--overlay", type=Path, help="also write the map over the image (.png)")
    p.add_argument(
        "--model",
        type=Path,
        default=default_model(),
        help="ONNX saliency model meeting the contract of models/gbvs_saliency.md",
    )
    p.add_argument(
        "--threshold",
        type=float,
        default=DEFAULT_THRESHOLD,
        help="T of the paper's eq. 5; the overlay outlines C >= T (default %(default)s)",
    )
    p.add_argument(
        "--no-faces", action="store_true", help="leave faces out: C = max(saliency, mask)"
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if not 0.0 <= args.threshold <= 1.0:
        raise InputError(f"--threshold must be in [0, 1], got {args.threshold}")
    check_image_file(args.out, "content map")
    if args.overlay is not None:
        check_image_file(args.overlay, "overlay")

    from adaproj_edge.content.contentmap import content_map_for
    from adaproj_edge.content.mask import load_mask
    from adaproj_edge.content.model import SaliencyModel
    from adaproj_edge.content.overlay import overlay, to_gray
    from adaproj_edge.fileio import read_image, write_image

    image = read_image(args.image)
    h, w = image.shape[:2]
    mask = None if args.mask is None else load_mask(args.mask, (w, h))
    model = SaliencyModel(args.model)
    cmap = content_map_for(image, mask, model, threshold=args.threshold, faces=not args.no_faces)
    write_image(args.out, to_gray(cmap.full_size()))
    if args.overlay is not None:
        write_image(args.overlay, overlay(image, cmap))
    share = float(cmap.salient().mean())
    faces = "" if args.no_faces else f"; {len(cmap.faces)} face(s)"
    print(f"wrote {args.out} ({w}x{h}); {share:.0%} salient (C >= {cmap.threshold}){faces}")
    return 0
