"""The one way inputs reach the runtime, live or replayed (as ArduPilot's DAL does).

On the device, one reader thread per sensor puts :data:`Input` values on a queue
(:mod:`adaproj_edge.app.live`); in a replay, the session reader yields them
(:mod:`adaproj_edge.app.replay`). Both hand each one to :func:`feed`.
"""

from __future__ import annotations

from dataclasses import dataclass

from adaproj_edge.app.runtime import Runtime
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample


@dataclass(frozen=True)
class SourceFault:
    """A sensor that failed to deliver: ``source`` is "depth", "imu" or "button",
    ``message`` says what happened and what to check."""

    source: str
    message: str


Input = DepthFrame | ImuSample | ButtonEvent | SourceFault
"""What a sensor delivers to the runtime."""

RECORDED = (DepthFrame, ImuSample, ButtonEvent)
"""Inputs a session holds as records."""


def feed(runtime: Runtime, item: Input) -> None:
    """Hand one input to the runtime."""
    if isinstance(item, DepthFrame):
        runtime.on_depth(item)
    elif isinstance(item, ImuSample):
        runtime.on_imu(item)
    elif isinstance(item, ButtonEvent):
        runtime.on_button(item)
    else:
        runtime.on_source_fault(item.source, item.message)
