"""Scratch arrays reused from frame to frame, owned by one estimator."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


class Workspace:
    """Scratch arrays by name, shape and type, reused from frame to frame: frame-sized
    temporaries allocated afresh are returned to the OS after each frame and cost page
    faults (about as much as the arithmetic on them) when allocated again.

    An array handed out stays valid until the same name is asked for again (the next
    frame, or a later step of this one that reuses it on purpose). One workspace
    serves one thread: an estimator owns one.
    """

    def __init__(self) -> None:
        self.arrays: dict[tuple[str, tuple[int, ...], str], NDArray[Any]] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype: type[Any] = np.float64) -> NDArray[Any]:
        """The scratch array ``name`` of ``shape`` and ``dtype`` (contents undefined)."""
        key = (name, shape, np.dtype(dtype).str)
        if key not in self.arrays:
            if len(self.arrays) > 64:  # sizes changed (another frame or lattice size)
                self.arrays.clear()
            self.arrays[key] = np.empty(shape, dtype)
        return self.arrays[key]
