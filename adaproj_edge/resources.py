"""Files the product ships beside its code: board files and calibrations (``hw/``), the
saliency model and the face cascade (``models/``) and the built-in recording
(``adaproj_edge/data/``).

``adaproj_edge/hw`` and ``adaproj_edge/models`` are symbolic links to the repository's
top-level ``hw/`` and ``models/``: a checkout (an editable install, ``tools/adaproj``)
reads them in place, and a wheel carries their files inside the package (package data
in ``pyproject.toml``). Every path to a shipped file goes through here.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent


def boards_dir() -> Path:
    """Board files (``hw/boards/*.toml``), found by name by ``--board NAME``."""
    return PACKAGE / "hw" / "boards"


def default_model() -> Path:
    """The default saliency model (``models/gbvs_saliency.onnx``)."""
    return PACKAGE / "models" / "gbvs_saliency.onnx"


def face_cascade() -> Path:
    """The face detector's cascade (``models/lbpcascade_frontalface.xml``)."""
    return PACKAGE / "models" / "lbpcascade_frontalface.xml"


def default_session() -> Path:
    """The built-in recording ``adaproj replay`` plays by default: a hand-held device in
    front of a convex column (also a test fixture)."""
    return PACKAGE / "data" / "cylinder.mcap"
