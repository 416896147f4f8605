"""Where the commands write: checked before any work, so a bad path costs nothing.

A command calls these first in its ``run``: an output that cannot be written (a folder
where a file is wanted, a file where a folder is wanted, an unknown image extension, a
folder nobody may write into) ends the command with one line and exit status 2 before
a surface is loaded or a warp computed. Only light modules are imported here.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from adaproj_edge.errors import InputError


def _nearest_existing(path: Path) -> Path:
    """``path`` or its closest ancestor that exists."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _check_can_create_in(folder: Path, what: str, target: Path) -> None:
    """Raise :class:`InputError` unless files can be created in ``folder`` (or, when it
    does not exist yet, in its closest existing ancestor: the write makes the rest)."""
    base = _nearest_existing(folder)
    if not base.is_dir():
        raise InputError(f"cannot write {what} {target}: {base} is not a folder")
    try:  # the real test (permissions, read-only file systems, root included)
        with tempfile.NamedTemporaryFile(dir=base, prefix=".adaproj-probe-"):
            pass
    except OSError as e:
        raise InputError(
            f"cannot write {what} {target}: cannot create files in {base} ({e.strerror or e})"
        ) from None


def check_output_file(path: Path | str, what: str, suffixes: Iterable[str] | None = None) -> Path:
    """Check that the file ``path`` can be written, before any work.

    Parameters
    ----------
    path : path
        The output file; its folder is made by the write if it does not exist.
    what : str
        What the file is, for the message (``"warp file"``, ``"frame"``).
    suffixes : iterable of str, optional
        Allowed extensions, lower case with the dot (``(".npz",)``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        One line saying what is wrong.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{what} {path} is a folder; give a file name")
    if path.exists() and not path.is_file():
        raise InputError(f"{what} {path} exists and is not a regular file")
    if suffixes is not None:
        allowed = list(suffixes)
        if path.suffix.lower() not in allowed:
            names = (
                ", ".join(allowed[:-1]) + " or " + allowed[-1] if len(allowed) > 1 else allowed[0]
            )
            raise InputError(f"{what} {path}: the name must end in {names}")
    _check_can_create_in(path.parent, what, path)
    return path


def check_output_dir(path: Path | str, what: str) -> Path:
    """Check that the folder ``path`` can receive files (made if it does not exist).

    Parameters
    ----------
    path : path
        The output folder.
    what : str
        What it is, for the message (``"output folder"``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        One line saying what is wrong.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{what} {path} is a file, not a folder")
    _check_can_create_in(path, what, path)
    return path


def check_image_file(path: Path | str, what: str) -> Path:
    """:func:`check_output_file` for an image: PNG or JPEG by its extension, as
    :func:`adaproj_edge.fileio.write_image` writes it."""
    from adaproj_edge.fileio import IMAGE_FORMATS

    return check_output_file(path, what, IMAGE_FORMATS)
