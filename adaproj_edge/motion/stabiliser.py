"""Image stabilisation for a hand-held projector: cancel the tremor, follow deliberate
motion, stay inside the margin.

The frame on the projector is rendered for where the device points; the display shows
it as a *stabilised* virtual projector would, one whose orientation ``R_s`` follows the
device's ``R`` smoothly: each refresh shows the frame moved by the correction
``C = R_s^T R`` (the homography ``K C K^-1``, :mod:`adaproj_edge.render.reproject`),
with ``R`` predicted to the moment the frame is lit (:mod:`.prediction`).

The filter
----------
A first-order follower on the rotation group, as a camera stabiliser's:
``R_s <- R_s exp(a log(R_s^T R))`` at every refresh, ``a = 1 - exp(-dt / tau)``. Its
time constant adapts to how fast the device is deliberately turned (the gyro rate
low-passed twice with ``speed_tau_s``, which takes the 8-12 Hz tremor out):
``tau = tau_moving + (tau_still - tau_moving) / (1 + (v / moving_rate)^2)``. Held still
(``v`` well under ``moving_rate``), ``tau`` is ``tau_still`` (seconds): the tremor and
the slow sway of the hand are cancelled and the picture stays where it is on the
surface; turned on purpose, ``tau`` drops towards ``tau_moving`` and the picture follows
with little lag.

The follower starts as a running mean of the orientations it is given (the pull is at
least ``dt / age`` while its age is under the time constant): started on the first
orientation alone, it would keep that instant's tremor and let it decay with
``tau_still_s``, a drift of the picture over the first seconds.

The margin
----------
The content is rendered ``margin`` of the frame inside each edge, so the correction has
room. When the correction uses more than ``ease_from`` of that room the follower is
pulled towards the device (harder the closer to the edge): the picture eases back
instead of being cut; at the edge it is held there (the content never leaves the
frame). The pull aims at the device's orientation low-passed with ``usage_tau_s`` (and
carried along by the deliberate rate, as the follower is): aimed at the orientation of
the moment, it let a share of a strong tremor through. ``margin = 0`` turns
stabilisation off (``C`` is the identity).

Turned on purpose, or trembling?
--------------------------------
The deliberate rate ``v`` is the low-passed rate: under a strong tremor (0.5 degrees
RMS) what the low-pass leaves of it is about ``moving_rate`` itself, while the device
is held still. It sets the follower's time constant (a blend, harmless there), but it
cannot say *whether* the device is turned on purpose: :attr:`Stabiliser.turning` asks
the rotation that rate accumulates over ``turn_window_s`` (its mean,
:class:`~adaproj_edge.motion.rates.WindowMean`) to be over ``moving_rate``. The
tremor's residue reverses every 40-125 ms (4-12 Hz) and averages out over the window;
a turn keeps one direction, and a turn of 20 degrees a second shows within ~0.13 s.
The rate of the moment must be over ``moving_rate`` too: the turn ends when the hand
stops (~0.3 s after, the low-passes' decay), not a window later.

Gyro bias
---------
A gyro's zero-rate offset integrates into a steady turn: it is learnt while the device
is held still (:class:`~adaproj_edge.motion.rates.GyroBias`) and removed before
integration. It is learnt from the low-passed rate, as the motion tracker's is: averaged
raw, a 0.5-degree tremor (~1 rad/s RMS of rate) left it off by up to 0.05 rad/s over
12 s held still, and that error is a steady "turn" in the deliberate rate (the
window's mean of it went over ``moving_rate``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rotations import rotation_vector
from adaproj_edge.motion.prediction import GyroTrack, PredictionSettings, small_rotation
from adaproj_edge.motion.rates import GyroBias, LowPass2, WindowMean
from adaproj_edge.render.reproject import margin_usage


@dataclass(frozen=True)
class StabiliserSettings:
    """Tuning of the stabiliser (fractions of the frame, seconds, rad/s).

    margin : float
        Room kept on each side, a fraction of the frame's width and height; 0: off.
    tau_still_s, tau_moving_s : float
        The follower's time constant held still and turned on purpose.
    moving_rate : float
        Deliberate turning rate at which the time constant is halfway between the two.
    speed_tau_s : float
        Time constant of each of the two low-passes that tell the deliberate rate.
    turn_window_s : float
        Window over which the deliberate rate's mean tells a turn from a tremor
        (:attr:`Stabiliser.turning`).
    ease_from : float
        Share of the margin in use beyond which the picture is eased back.
    ease_tau_s : float
        Time constant of the pull back when the margin is all used.
    usage_tau_s : float
        Low-pass of the margin's use that decides the pull (tremor taken out).
    bias_tau_s, still_rate, still_hold_s, max_bias : float
        The gyro bias's learning (:class:`~adaproj_edge.motion.rates.GyroBias`).
    prediction : PredictionSettings
    """

    margin: float = 0.04
    tau_still_s: float = 1.0
    tau_moving_s: float = 0.12
    moving_rate: float = 0.04
    speed_tau_s: float = 0.08
    turn_window_s: float = 0.25
    ease_from: float = 0.5
    ease_tau_s: float = 0.05
    usage_tau_s: float = 0.1
    bias_tau_s: float = 20.0
    still_rate: float = 0.05
    still_hold_s: float = 0.3
    max_bias: float = 0.05
    prediction: PredictionSettings = field(default_factory=PredictionSettings)

    @property
    def enabled(self) -> bool:
        """Whether stabilisation is on (a margin to move in)."""
        return self.margin > 0


@dataclass(frozen=True)
class Correction:
    """One refresh's correction.

    Attributes
    ----------
    C : (3, 3) float array
        ``R_s^T R``: rotation from the shown orientation to the stabilised one.
    usage : float
        Share of the margin the correction uses (0..1).
    tau_s : float
        The follower's time constant at this refresh.
    """

    C: FloatArray
    usage: float
    tau_s: float


class Stabiliser:
    """Gyro in, one correction per refresh out (pure: times are given, never read).

    Parameters
    ----------
    K : (3, 3) float array
        Projector intrinsics.
    size : (width, height)
        The projector frame in pixels.
    settings : StabiliserSettings
    """

    def __init__(
        self, K: FloatArray, size: tuple[int, int], settings: StabiliserSettings | None = None
    ) -> None:
        self.settings = s = settings or StabiliserSettings()
        self.K = np.asarray(K, dtype=np.float64)
        self.size = size
        self.track = GyroTrack(s.prediction)
        self._deliberate = LowPass2(s.speed_tau_s)
        self._turn = WindowMean(s.turn_window_s)
        self._bias = GyroBias(
            s.bias_tau_s, s.still_rate, s.still_hold_s, s.max_bias, s.speed_tau_s, smooth=True
        )
        self.R_s: FloatArray | None = None
        self._last_step_ns: int | None = None
        self._age_s = 0.0  # since the follower started
        self._usage = 0.0
        self._R_calm: FloatArray | None = None  # the device's orientation, tremor taken out

    # ------------------------------------------------------------------ input
    def add_gyro(self, t_ns: int, rate: FloatArray) -> None:
        """One gyro sample: rate (3,) in rad/s in frame P, at sensor time ``t_ns``."""
        s = self.settings
        last = self.track.last_ns
        w = np.asarray(rate, dtype=np.float64)
        if not self.track.add(t_ns, w):
            return
        if last is None or t_ns - last > s.prediction.max_gap_s * 1e9:
            self._bias.reset_stillness()
            return
        dt = (t_ns - last) * 1e-9
        self._turn.update(self._deliberate.update(w - self.track.bias, dt), dt)
        self._bias.update(w, dt)
        self.track.bias = self._bias.value.copy()

    def reset(self) -> None:
        """Start afresh (after an IMU fault): no correction until samples come again."""
        self.track.reset()
        self.R_s = None
        self._last_step_ns = None
        self._age_s = 0.0
        self._deliberate.reset()
        self._turn.reset()
        self._bias.reset_stillness()
        self._usage = 0.0
        self._R_calm = None

    @property
    def deliberate_rate(self) -> float:
        """The low-passed turning rate (rad/s), tremor taken out."""
        return float(np.linalg.norm(self._deliberate.value))

    @property
    def turning_rate(self) -> float:
        """The deliberate rate's mean over ``turn_window_s`` (rad/s): the rotation it
        accumulated over that window, divided by it (a tremor's residue averages out)."""
        return float(np.linalg.norm(self._turn.value))

    @property
    def turning(self) -> bool:
        """Whether the device is being turned on purpose, not only trembling: the
        deliberate rate over ``moving_rate`` now and over the window
        (:attr:`turning_rate`). The window's mean tells the turn from the tremor; the
        rate of the moment ends the turn when the hand stops, not a window later."""
        mr = self.settings.moving_rate
        return self.turning_rate >= mr and self.deliberate_rate >= mr

    @property
    def bias(self) -> FloatArray:
        """The gyro bias estimate (3,) rad/s in frame P."""
        return self.track.bias.copy()

    # ------------------------------------------------------------------ output
    def step(self, t_lit_ns: int) -> Correction:
        """Advance the follower to ``t_lit_ns`` (when the next frame is lit) and return
        the correction to show it with."""
        s = self.settings
        R = self.track.predict(t_lit_ns)
        if not s.enabled or self.track.last_ns is None:
            return Correction(np.eye(3), 0.0, 0.0)
        if self.R_s is None or self._last_step_ns is None or self._R_calm is None:
            self.R_s, self._last_step_ns, self._age_s, self._R_calm = R, t_lit_ns, 0.0, R
            return Correction(np.eye(3), 0.0, s.tau_still_s)
        dt = max(0.0, (t_lit_ns - self._last_step_ns) * 1e-9)
        self._last_step_ns = t_lit_ns
        self._age_s += dt
        v = self.deliberate_rate / s.moving_rate
        tau = s.tau_moving_s + (s.tau_still_s - s.tau_moving_s) / (1.0 + v * v)
        # carried along by the low-passed rate (no lag behind a steady turn or a bias
        # not yet learnt), then pulled towards the device
        carried = small_rotation(self._deliberate.value * dt)
        self.R_s = self.R_s @ carried
        a = 1.0 - math.exp(-dt / tau)
        if 0.0 < self._age_s < tau:  # (two steps at one time: dt and age both 0)
            # started: a running mean of the orientations so far, not the first one
            # (which holds that instant's tremor, then left to decay with tau_still)
            a = max(a, dt / self._age_s)
        self.R_s = _toward(self.R_s, R, a)
        usage = margin_usage(self.K, self.R_s.T @ R, self.size, s.margin)
        low = 1.0 - math.exp(-dt / s.usage_tau_s)
        self._usage += (usage - self._usage) * low
        self._R_calm = _toward(self._R_calm @ carried, R, low)
        if self._usage > s.ease_from:
            # eased back: a pull whose rate grows smoothly from 0 at ease_from to
            # 1 / ease_tau_s at the edge, decided on the low-passed use and aimed at
            # the low-passed orientation (both without the tremor)
            x = min(1.0, (self._usage - s.ease_from) / (1.0 - s.ease_from))
            self.R_s = _toward(self.R_s, self._R_calm, 1.0 - math.exp(-dt * x * x / s.ease_tau_s))
            usage = margin_usage(self.K, self.R_s.T @ R, self.size, s.margin)
        for _ in range(3):  # at the edge: held there (usage is nearly linear in angle)
            if usage <= 1.0:
                break
            self.R_s = _toward(self.R_s, R, 1.0 - 1.0 / usage)
            usage = margin_usage(self.K, self.R_s.T @ R, self.size, s.margin)
        return Correction(self.R_s.T @ R, min(usage, 1.0), tau)


def _toward(R_s: FloatArray, R: FloatArray, a: float) -> FloatArray:
    """``R_s`` moved the fraction ``a`` of the way to ``R`` (geodesic)."""
    out: FloatArray = R_s @ small_rotation(a * rotation_vector(R_s.T @ R))
    return out
