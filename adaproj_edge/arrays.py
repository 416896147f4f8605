"""The array types used across the package (one home, so every module means the same)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
"""Coordinates, depths, energies: float64."""
Float32Array = NDArray[np.float32]
"""Images and maps stored compactly: float32."""
IntArray = NDArray[np.intp]
"""Indices (triangles, edges, vertices)."""
BoolArray = NDArray[np.bool_]
"""Masks."""
Image = NDArray[np.uint8]
"""An 8-bit image: (H, W, 3) BGR or (H, W) grey."""
