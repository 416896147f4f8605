"""Sub-commands of ``adaproj``: one module each, each with ``register(subparsers)``.

To add a command, write ``adaproj_edge/commands/<name>.py`` with a ``register``
function that adds its parser and sets ``run`` (``args -> int``), then add the module's
name to :data:`MODULES` (one line: the order is the order of ``adaproj --help``).
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Iterator
from typing import Any

Register = Callable[["argparse._SubParsersAction[Any]"], None]

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
    "replay",
    "calibrate",
)


def registry() -> Iterator[Register]:
    """The ``register`` function of every command module, in :data:`MODULES` order."""
    for name in MODULES:
        module = importlib.import_module(f"adaproj_edge.commands.{name}")
        yield module.register
