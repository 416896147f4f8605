"""The optional parts of the install (pyproject's extras) and what to say when one is
missing.

The core install runs everything that needs no hardware and no host tools; the extras
add a part each: ``device`` (DepthAI and smbus2, on the projector), ``host``
(smpclient, for ``adaproj push`` and ``adaproj device`` on a computer) and ``sim``
(NVIDIA Warp's BVH ray caster for large meshes). A command that meets a missing one
says, in one line, which extra to install (:func:`missing_extra`, used by
:func:`adaproj_edge.cli.main`).
"""

from __future__ import annotations

from dataclasses import dataclass

from adaproj_edge.errors import AdaprojError

PACKAGE = "adaproj-edge"


@dataclass(frozen=True)
class Extra:
    """One extra of the install.

    Attributes
    ----------
    name : str
        The extra's name in ``pip install 'adaproj-edge[NAME]'``.
    what : str
        What it brings, as a noun phrase ("the host tools").
    """

    name: str
    what: str

    @property
    def install(self) -> str:
        """The command that installs it."""
        return f"pip install '{PACKAGE}[{self.name}]'"


DEVICE = Extra("device", "the device drivers (DepthAI, smbus2)")
HOST = Extra("host", "the host tools (smpclient)")
SIM = Extra("sim", "NVIDIA Warp's BVH ray caster for meshes")

BY_MODULE: dict[str, Extra] = {
    "depthai": DEVICE,
    "smbus2": DEVICE,
    "smpclient": HOST,
    "warp": SIM,
}
"""The extra that brings each optional top-level module."""


class MissingExtraError(AdaprojError):
    """A command needs an extra that is not installed; the message is the rest of the
    sentence "adaproj COMMAND needs ...", ending with the command that installs it."""

    def __init__(self, extra: Extra, why: str = "") -> None:
        self.extra = extra
        reason = f" ({why})" if why else ""
        super().__init__(f"{extra.what}{reason}: {extra.install}")


def missing_extra(error: ModuleNotFoundError) -> MissingExtraError | None:
    """The extra behind a failed import, or None when the module is not an extra's.

    Parameters
    ----------
    error : ModuleNotFoundError
        The failed import.

    Returns
    -------
    MissingExtraError or None
        Its message names the extra and how to install it.
    """
    top = (error.name or "").split(".")[0]
    extra = BY_MODULE.get(top)
    return None if extra is None else MissingExtraError(extra)
