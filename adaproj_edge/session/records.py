"""Record types of a session that have no device protocol of their own."""

from __future__ import annotations

from dataclasses import dataclass

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


@dataclass(frozen=True)
class SerialTraffic:
    """Raw bytes seen on the serial link; ``direction`` is ``"rx"`` (from the host) or
    ``"tx"`` (to the host). Decoding them (SMP) is the link's business, not the session's.
    """

    receive_ns: int
    direction: str
    data: bytes


@dataclass(frozen=True)
class TruthPose:
    """Ground truth (simulated sessions only): the projector pose ``T_W_P`` at ``t_ns``.

    World frame W = the projector frame P at the start of the session. ``position`` is
    the projector centre in W (metres), ``quaternion`` (x, y, z, w) rotates P into W.
    """

    t_ns: int
    position: Vec3
    quaternion: Quat

    @property
    def receive_ns(self) -> int:
        return self.t_ns


@dataclass(frozen=True)
class PatternShown:
    """A structured-light pattern put on the display (calibration sessions): when
    (``t_ns``, the display call on the device's monotonic clock), for which pose, and
    which pattern of the set (``index``, ``name``)."""

    t_ns: int
    pose: int
    index: int
    name: str

    @property
    def receive_ns(self) -> int:
        return self.t_ns
