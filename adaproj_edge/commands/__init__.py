"""Sub-commands of ``adaproj``: one module each, each with ``register(subparsers)``.

To add a command, write ``adaproj_edge/commands/<name>.py`` with a ``register``
function that adds its parser and sets ``run`` (``args -> int``), then list it below.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

Register = Callable[["argparse._SubParsersAction[Any]"], None]

REGISTRY: list[Register] = []

from adaproj_edge.commands import saliency  # noqa: E402

REGISTRY.append(saliency.register)
from adaproj_edge.commands import link  # noqa: E402

REGISTRY.append(link.register)
from adaproj_edge.commands import push  # noqa: E402

REGISTRY.append(push.register)
from adaproj_edge.commands import device  # noqa: E402

REGISTRY.append(device.register)
from adaproj_edge.commands import record  # noqa: E402

REGISTRY.append(record.register)
from adaproj_edge.commands import simulate_session  # noqa: E402

REGISTRY.append(simulate_session.register)
from adaproj_edge.commands import demo, simulate, surface, warp  # noqa: E402

REGISTRY.extend([demo.register, warp.register, simulate.register, surface.register])
from adaproj_edge.commands import replay, run  # noqa: E402

REGISTRY.extend([run.register, replay.register])
