"""Content files -> what the warp needs: one path for every place content comes in
(the device runtime, ``adaproj link`` alone, the command line).

The image must decode (PNG or JPEG); a mask may have any size of the content's aspect
ratio (:mod:`adaproj_edge.content.mask`) and is brought to the content's size.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from adaproj_edge.arrays import Float32Array, Image
from adaproj_edge.content.mask import load_mask
from adaproj_edge.fileio import read_image


@dataclass(frozen=True)
class ContentFiles:
    """A decoded content item.

    Attributes
    ----------
    image : (h, w, 3) uint8 array
        The content, BGR.
    mask : (h, w) float32 array in [0, 1], or None
        The user mask at the content's size.
    """

    image: Image
    mask: Float32Array | None

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
    MaskError
        The mask cannot be read or does not have the image's aspect ratio.
    """
    img = read_image(image)
    h, w = img.shape[:2]
    return ContentFiles(img, None if mask is None else load_mask(mask, (w, h)))
