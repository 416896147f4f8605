"""Content files -> what the warp needs: one path for every place content comes in
(the device runtime, ``adaproj link`` alone, the command line).

The image must decode (PNG or JPEG); a clip (:mod:`adaproj_edge.content.video`) stands
in by its first frame. A mask may have any size of the content's aspect ratio
(:mod:`adaproj_edge.content.mask`) and is brought to the content's size.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from adaproj_edge.arrays import Float32Array, Image
from adaproj_edge.content.mask import load_mask
from adaproj_edge.content.video import VideoReader, is_video_name
from adaproj_edge.errors import ContentError
from adaproj_edge.fileio import read_image


@dataclass(frozen=True)
class ContentFiles:
    """A decoded content item.

    Attributes
    ----------
    image : (h, w, 3) uint8 array
        The content, BGR (a clip's first frame).
    mask : (h, w) float32 array in [0, 1], or None
        The user mask at the content's size.
    video : bool
        The content is a clip.
    """

    image: Image
    mask: Float32Array | None
    video: bool = False

    @property
    def size(self) -> tuple[int, int]:
        """The content's (w, h) in pixels."""
        return int(self.image.shape[1]), int(self.image.shape[0])


def read_content(
    image: str | os.PathLike[str], mask: str | os.PathLike[str] | None = None
) -> ContentFiles:
    """Read a content image and its optional user mask.

    Raises
    ------
    ImageError
        The image cannot be read.
    ContentError
        The clip's first frame cannot be decoded.
    MaskError
        The mask cannot be read or does not have the image's aspect ratio.
    """
    video = is_video_name(Path(image).name)
    img = first_frame(Path(image)) if video else read_image(image)
    h, w = img.shape[:2]
    if mask is None:
        return ContentFiles(img, None, video)
    return ContentFiles(img, load_mask(mask, (w, h), f"mask {Path(mask).name}"), video)


def first_frame(path: Path) -> Image:
    """The first frame of a clip (what stands for it where a still is needed)."""
    with VideoReader(path) as reader:
        frame = reader.next()
    if frame.image is None:
        raise ContentError(f"{path.name}: {frame.error}")
    return frame.image
