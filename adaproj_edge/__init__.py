"""adaproj-edge: content- and surface-aware projection for a handheld pico-projector."""

import os

__version__ = "0.1.0"

MAX_IMAGE_PIXELS = 40_000_000
"""Width times height of the largest image decoded (:mod:`adaproj_edge.fileio`)."""

# OpenCV's own refusal of larger images, checked on its decoder's header before pixels
# are allocated: a backstop behind fileio's header check, in effect when the package is
# imported before cv2 is (as by the ``adaproj`` command).
os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(MAX_IMAGE_PIXELS))
