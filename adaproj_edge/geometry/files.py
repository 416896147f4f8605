"""Reading input files with one clear error for each way it can fail."""

from __future__ import annotations

import os
from pathlib import Path

from adaproj_edge.errors import InputError


def read_input(path: str | os.PathLike[str], what: str) -> bytes:
    """The bytes of ``path``; :class:`InputError` naming ``what`` if it cannot be read."""
    path = Path(path)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{what} not found: {path}") from None
    except IsADirectoryError:
        raise InputError(f"{what} {path} is a directory") from None
    except OSError as e:
        raise InputError(f"cannot read {what} {path}: {e.strerror}") from None
