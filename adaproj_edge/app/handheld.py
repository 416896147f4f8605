"""How the picture behaves in the hand, scored refresh by refresh on a simulated
session's ground truth: where content points land on the true surface when each
displayed frame is lit.

At each refresh (:class:`~adaproj_edge.app.display_loop.Refresh`) a set of content
points (a 5x5 grid over the content, and a vertical pair at its centre) is followed
from the content to the frame (the shown warp, inverted on its mesh), through the
refresh's correction (``H^-1 = K C^T K^-1``) to a displayed pixel, along that pixel's
ray from the true pose at the lit time (interpolated between the session's
``/truth/pose`` records) onto the true surface. The same points are followed as the
runtime before the display loop would have shown them (the frame as rendered, no
inset, no correction): "off", measured in the same run.

The figures (:meth:`HandheldScorer.summary`, ``summary.json`` ``handheld``):

- ``jitter_mm_rms``: RMS of the frame-to-frame motion of the content points on the
  surface, over consecutive refreshes while the runtime projects warped content and
  the user holds the device still (the simulator's still phases, from 0.3 s after each
  move; every refresh when the session does not say), with ``jitter_off_mm_rms`` and
  their ratio;
- ``drift_mm_10s``: over each still phase of at least 10.5 s, how far the points' mean
  position over its second 1-s stretch is from that over the 1-s stretch 9 s later
  (the largest), with ``drift_off_mm_10s``; None without so long a still phase;
- ``upright_error_deg_max``: the largest angle between the content's vertical (the
  centre pair, top to bottom) and gravity projected on the surface there, over the
  refreshes showing warped content on a surface steeper than 30 degrees while the
  device is held (the same still phases as the jitter's); ``upright_error_deg_max_all``
  over every such refresh, deliberate turns included (the stabiliser follows a roll
  with some lag, and the content with it).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.app.display_loop import WARPED, Refresh
from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.rotations import rotation_matrix, rotation_of, rotation_vector
from adaproj_edge.render.content_points import content_points, frame_pixels
from adaproj_edge.render.reproject import inset_warp, map_points, rotation_homography
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.simulator import Scene

AFTER_MOVE_S = 0.3


class TruthTrack:
    """The true projector pose at any instant, interpolated between ``/truth/pose``
    records (rotation along the geodesic, position linearly)."""

    def __init__(self, keep: int = 4096) -> None:
        self._poses: deque[TruthPose] = deque(maxlen=keep)

    def add(self, pose: TruthPose) -> None:
        """A truth record (in time order; a repeated time is dropped)."""
        if self._poses and pose.t_ns <= self._poses[-1].t_ns:
            return
        self._poses.append(pose)

    @property
    def last_ns(self) -> int | None:
        """Time of the newest record."""
        return self._poses[-1].t_ns if self._poses else None

    def at(self, t_ns: int) -> tuple[FloatArray, FloatArray] | None:
        """``R_W_P`` (3, 3) and ``t_W_P`` (3,) at ``t_ns``; None outside the records."""
        poses = self._poses
        if not poses or t_ns < poses[0].t_ns or t_ns > poses[-1].t_ns:
            return None
        times = [p.t_ns for p in poses]
        k = int(np.searchsorted(times, t_ns))
        b = poses[k]
        a = poses[k - 1] if k > 0 else b
        f = 0.0 if b.t_ns == a.t_ns else (t_ns - a.t_ns) / (b.t_ns - a.t_ns)
        Ra, Rb = rotation_of(a.quaternion), rotation_of(b.quaternion)
        R = Ra @ rotation_matrix(f * rotation_vector(Ra.T @ Rb))
        p = (1 - f) * np.asarray(a.position) + f * np.asarray(b.position)
        return R, p


@dataclass(frozen=True)
class _Scored:
    t_ns: int
    on: FloatArray  # (P, 3) metres, W
    off: FloatArray
    upright_deg: float  # NaN: not measurable


class HandheldScorer:
    """Scores the refreshes of a replay on the session's ground truth.

    Parameters
    ----------
    scene : Scene
        The true surface (frame W).
    projector : Projector
    margin : float
        The stabilisation margin the frames were drawn with (0: off).
    hand : dict, optional
        The session's ``hand`` metadata (still phases, ``t0_ns``, ``gravity_w``).
    """

    def __init__(
        self,
        scene: Scene,
        projector: Projector,
        margin: float,
        hand: dict[str, Any] | None = None,
    ) -> None:
        self.scene = scene
        self.projector = projector
        self.K_inv = np.linalg.inv(projector.K)
        self.margin = margin
        self.hand = hand or {}
        g = np.asarray(self.hand.get("gravity_w", (0.0, 9.80665, 0.0)), dtype=np.float64)
        self.down = g / np.linalg.norm(g)
        self.truth = TruthTrack()
        self._pending: deque[Refresh] = deque()
        self._pixels: dict[tuple[int, bool], FloatArray] = {}
        self.scored: list[_Scored] = []

    # ------------------------------------------------------------------ inputs
    def add_truth(self, pose: TruthPose) -> None:
        """A truth record; refreshes lit before it are scored."""
        self.truth.add(pose)
        while self._pending and self._pending[0].lit_ns <= pose.t_ns:
            self._score(self._pending.popleft())

    def on_refresh(self, r: Refresh) -> None:
        """A refresh (scored once the truth has passed its lit time)."""
        if r.shown is None or r.shown.warp is None or r.shown.kind not in WARPED:
            return
        self._pending.append(r)

    def finish(self) -> None:
        """Score what the truth covers of the refreshes still waiting."""
        last = self.truth.last_ns
        while self._pending:
            r = self._pending.popleft()
            if last is not None and r.lit_ns <= last:
                self._score(r)

    # ------------------------------------------------------------------ scoring
    def _frame_pixels(self, r: Refresh, inset: bool) -> FloatArray:
        assert r.shown is not None and r.shown.warp is not None
        key = (r.shown.frame_id, inset)
        got = self._pixels.get(key)
        if got is None:
            warp = inset_warp(r.shown.warp, self.margin) if inset else r.shown.warp
            got = frame_pixels(warp, content_points(warp.content_size))
            self._pixels = {k: v for k, v in self._pixels.items() if k[0] == key[0]}
            self._pixels[key] = got
        return got

    def _land(self, R: FloatArray, p: FloatArray, uv: FloatArray) -> FloatArray:
        rays = np.concatenate([uv, np.ones((len(uv), 1))], axis=1) @ self.K_inv.T
        dirs = rays @ R.T
        t = self.scene.surface.intersect(np.broadcast_to(p, dirs.shape), dirs)
        out: FloatArray = p + t[:, None] * dirs
        return out

    def _score(self, r: Refresh) -> None:
        pose = self.truth.at(r.lit_ns)
        if pose is None:
            return
        R, p = pose
        H_inv = rotation_homography(self.projector.K, r.C.T) @ np.linalg.inv(r.glide)
        on_uv = map_points(H_inv, self._frame_pixels(r, inset=self.margin > 0))
        off_uv = self._frame_pixels(r, inset=False)
        on = self._land(R, p, on_uv)
        off = self._land(R, p, off_uv)
        self.scored.append(_Scored(r.lit_ns, on, off, self._upright(R, p, on_uv[-2:], on[-2:])))

    def _upright(self, R: FloatArray, p: FloatArray, uv: FloatArray, X: FloatArray) -> float:
        """Angle (degrees) between the content's down (top -> bottom of the pair) and
        gravity projected on the surface between them; NaN where not measurable."""
        v = X[1] - X[0]
        mid_uv = uv.mean(axis=0)
        around = self._land(R, p, mid_uv + np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]]))
        n = np.cross(around[1] - around[0], around[2] - around[0])
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(n))) or np.linalg.norm(n) == 0:
            return float("nan")
        n /= np.linalg.norm(n)
        g = self.down - np.dot(self.down, n) * n
        if np.linalg.norm(g) < 0.5:  # the surface is within 30 degrees of level
            return float("nan")
        cos = np.dot(v, g) / (np.linalg.norm(v) * np.linalg.norm(g))
        return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))

    # ------------------------------------------------------------------ figures
    def _still(self, t_ns: FloatArray) -> BoolArray:
        """Whether the user holds still at each time (every time without the hand's
        intent in the session)."""
        still = self.hand.get("still")
        if still is None:
            return np.ones(len(t_ns), dtype=np.bool_)
        t = (t_ns - int(self.hand.get("t0_ns", 0))) / 1e9
        out: BoolArray = np.zeros(len(t_ns), bool)
        for a, b in still:
            skip = AFTER_MOVE_S if a > 0 else 0.0
            out |= (t >= a + skip) & (t < b)
        return out

    def trajectories(self) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
        """Lit times (K,) ns, and the content points on the surface (K, P, 3) in
        millimetres, stabilised and off."""
        t = np.array([s.t_ns for s in self.scored], dtype=np.int64)
        if len(t) == 0:  # nothing lit was scored (no content shown on the surface)
            return t, np.zeros((0, 0, 3)), np.zeros((0, 0, 3))
        on = np.array([s.on for s in self.scored]) * 1e3
        off = np.array([s.off for s in self.scored]) * 1e3
        return t, on.reshape(len(t), -1, 3), off.reshape(len(t), -1, 3)

    def summary(self) -> dict[str, Any]:
        """The handheld figures (see the module's docstring); None where not measurable."""
        t, on, off = self.trajectories()
        out: dict[str, Any] = {"scored_refreshes": len(t)}
        if len(t) < 2:
            return {**out, "jitter_mm_rms": None, "drift_mm_10s": None}
        still = self._still(t.astype(np.float64))
        pairs = still[1:] & still[:-1]
        gap = np.diff(t) <= 1.5 * np.median(np.diff(t))  # consecutive refreshes only
        pairs &= gap
        jit = {name: _jitter(x, pairs) for name, x in (("on", on), ("off", off))}
        out["jitter_mm_rms"] = jit["on"]
        out["jitter_off_mm_rms"] = jit["off"]
        out["jitter_ratio"] = (
            round(jit["on"] / jit["off"], 4) if jit["on"] is not None and jit["off"] else None
        )
        out["drift_mm_10s"] = self._drift(t, on)
        out["drift_off_mm_10s"] = self._drift(t, off)
        up = np.array([s.upright_deg for s in self.scored])
        held = up[still & np.isfinite(up)]
        every = up[np.isfinite(up)]
        out["upright_error_deg_max"] = round(float(held.max()), 3) if held.size else None
        out["upright_error_deg_median"] = round(float(np.median(held)), 3) if held.size else None
        out["upright_error_deg_max_all"] = round(float(every.max()), 3) if every.size else None
        return out

    def _drift(self, t: NDArray[np.int64], x: FloatArray) -> float | None:
        still = self.hand.get("still")
        if still is None:
            return None
        rel = (t - int(self.hand.get("t0_ns", 0))) / 1e9
        worst: float | None = None
        for a, b in still:
            if b - a < 10.5:
                continue
            first = (rel >= a + 0.5) & (rel < a + 1.5)
            last = (rel >= a + 9.5) & (rel < a + 10.5)
            if not first.any() or not last.any():
                continue
            d = np.linalg.norm(np.nanmean(x[first], axis=0) - np.nanmean(x[last], axis=0), axis=1)
            d = d[np.isfinite(d)]
            if d.size:
                worst = max(worst or 0.0, float(d.max()))
        return None if worst is None else round(worst, 3)


def _jitter(x: FloatArray, pairs: BoolArray) -> float | None:
    """RMS frame-to-frame motion (mm) of points ``x`` (K, P, 3) over the ``pairs``
    (K - 1,) of consecutive refreshes that count."""
    d = np.linalg.norm(np.diff(x, axis=0), axis=2)[pairs[: len(x) - 1]]
    d = d[np.isfinite(d)]
    return round(float(np.sqrt(np.mean(d**2))), 4) if d.size else None
