"""Sub-commands of ``adaproj``: one module each, each with ``register(subparsers)``.

To add a command, write ``adaproj_edge/commands/<name>.py`` with a ``register``
function that adds its parser and sets ``run`` (``args -> int``), then add the module's
name to :data:`MODULES` (one line: the order is the order of ``adaproj --help``). The
command is called ``<name>`` with ``_`` spelled ``-``; its module's docstring begins
``adaproj <command>``, a colon and a summary (``adaproj --help`` lists the summary
without importing the module). A module imports only light things at its top (argparse,
pathlib, this package's ``errors``, ``_inputs`` and ``_outputs``) and the rest inside
``run``: ``adaproj warp --help`` then loads no numpy.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

MODULES: tuple[str, ...] = (
    "saliency",
    "link",
    "push",
    "device",
    "record",
    "simulate_session",
    "simulate_calibration",
    "demo",
    "warp",
    "simulate",
    "surface",
    "run",
    "doctor",
    "replay",
    "video",
    "calibrate",
)


def command_name(module: str) -> str:
    """The command a module implements: ``simulate_session`` -> ``simulate-session``."""
    return module.replace("_", "-")


def load(module: str) -> ModuleType:
    """Import a command module (it has ``register(subparsers)``)."""
    return importlib.import_module(f"{__name__}.{module}")


def summary(module: str) -> str:
    """A command's one-line summary, read from its module's docstring without importing
    it: the docstring's first paragraph, after the command's name and a colon."""
    text = Path(__file__).with_name(f"{module}.py").read_text(encoding="utf-8")
    quote = text[:3]
    if quote not in ('"""', "'''"):
        return ""
    first = text[3 : text.find(quote, 3)].split("\n\n", 1)[0]
    return " ".join(first.split(": ", 1)[-1].split()).rstrip(".")
