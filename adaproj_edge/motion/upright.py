"""The content's "up": gravity's estimate, followed with a dead band and a rate limit.

The warp places the content upright along an "up" in frame P. Gravity's estimate
(:class:`~adaproj_edge.motion.gravity.GravityFilter`) turns with the device, tremor
included; the content should not. The up handed to the warp follows it through

- two first-order low-passes of ``tau_s`` each (the tremor's roll, 7-13 Hz, cut by
  about 20 dB or more at 0.04 s);
- a dead band: held while the low-passed estimate stays within ``dead_band_deg`` of
  it; once it is further, turned towards it until within a fifth of the band (no
  steady offset after a deliberate roll);
- a rate limit: turned by at most ``max_rate_deg_s`` a second, so a glitch never swings
  the picture, while a deliberate 20-degree roll is followed in well under a second.

Before gravity's estimate is trusted the up is None (the caller's default); the first
trusted estimate is taken as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.motion.gravity import GravityFilter, GravitySettings


@dataclass(frozen=True)
class UprightSettings:
    """The content's up (seconds, degrees, degrees a second) and the gravity estimate."""

    tau_s: float = 0.04
    dead_band_deg: float = 0.3
    max_rate_deg_s: float = 60.0
    gravity: GravitySettings = field(default_factory=GravitySettings)


def _toward(a: FloatArray, b: FloatArray, angle: float) -> FloatArray:
    """Unit vector ``a`` turned by ``angle`` (radians) towards unit vector ``b``."""
    c = float(np.clip(np.dot(a, b), -1.0, 1.0))
    between = math.acos(c)
    if between <= angle or between < 1e-12:
        return b.copy()
    ortho = b - c * a
    ortho /= np.linalg.norm(ortho)
    out: FloatArray = math.cos(angle) * a + math.sin(angle) * ortho
    return out


class Upright:
    """IMU samples in frame P in, the content's up (unit vector in P) out.

    Parameters
    ----------
    settings : UprightSettings
    """

    def __init__(self, settings: UprightSettings | None = None) -> None:
        self.settings = settings or UprightSettings()
        self.gravity = GravityFilter(self.settings.gravity)
        self._a: FloatArray | None = None
        self._b: FloatArray | None = None
        self._up: FloatArray | None = None
        self._chasing = False
        self._last_ns: int | None = None

    def reset(self) -> None:
        """Forget everything (after an IMU fault): None until gravity is trusted again."""
        self.gravity.reset()
        self._a = self._b = self._up = None
        self._chasing = False
        self._last_ns = None

    def update(
        self,
        t_ns: int,
        accel: FloatArray,
        rate: FloatArray,
        still: bool = True,
        offset: FloatArray | None = None,
        offset_s: float | None = None,
    ) -> None:
        """One sample (as :meth:`GravityFilter.update`)."""
        s = self.settings
        self.gravity.update(t_ns, accel, rate, still, offset, offset_s)
        dt = 0.0 if self._last_ns is None else min(0.1, max(0.0, (t_ns - self._last_ns) * 1e-9))
        self._last_ns = t_ns
        g = self.gravity.up
        if g is None or not self.gravity.ready:
            return
        if self._a is None or self._b is None or self._up is None:
            self._a, self._b, self._up = g.copy(), g.copy(), g.copy()
            return
        k = 1.0 - math.exp(-dt / s.tau_s)
        self._a += k * (g - self._a)
        self._b += k * (self._a - self._b)
        target = self._b / np.linalg.norm(self._b)
        off = math.degrees(math.acos(float(np.clip(np.dot(self._up, target), -1.0, 1.0))))
        if off > s.dead_band_deg:
            self._chasing = True
        elif off <= s.dead_band_deg / 5:
            self._chasing = False
        if self._chasing:
            self._up = _toward(self._up, target, math.radians(s.max_rate_deg_s) * dt)

    @property
    def up(self) -> FloatArray | None:
        """The content's up (3,), unit, frame P; None before gravity is trusted."""
        return None if self._up is None else self._up.copy()
