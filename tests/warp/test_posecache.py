"""The pose cache: keys, the node-by-node surface check, bounds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.app.warps import WarpSource
from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.posecache import (
    PoseCache,
    common_nodes,
    pose_key,
    surface_turn,
    surfaces_agree,
    surfaces_match,
)


@dataclass
class _Entry:
    depth: FloatArray
    frames: int = 1


def test_lattices_of_two_resolutions_compare_at_their_common_nodes() -> None:
    coarse = np.arange(21 * 21, dtype=np.float64).reshape(21, 21)
    fine = np.full((81, 81), -1.0)
    fine[::4, ::4] = coarse
    for a, b in ((fine, coarse), (coarse, fine)):
        pair = common_nodes(a, b)
        assert pair is not None and np.array_equal(pair[0], pair[1])
    assert common_nodes(np.zeros((30, 30)), coarse) is None  # no common nodes
    # but a warp made from the unsnapped (noisier) lattice never serves a snapped one
    entry = _Entry(coarse + 1.5)
    assert surfaces_match(coarse + 1.5, entry.depth, 0.01, 0.97)
    assert not surfaces_match(np.where(fine < 0, 7.0, fine + 1.5), entry.depth, 0.01, 0.97)


def test_pose_cache_is_bounded_and_checks_the_depth() -> None:
    depth = np.full((21, 21), 1.5)

    def entry(scale: float) -> _Entry:
        return _Entry(depth * scale)

    cache: PoseCache[_Entry] = PoseCache(2)
    entries = [entry(1.0 + 0.1 * k) for k in range(3)]
    for k, e in enumerate(entries):
        cache.put((k,), e)
    assert len(cache) == 2 and cache.get((0,), depth) is None  # the oldest went
    assert cache.get((2,), depth * 1.2) is entries[2]
    assert cache.get((1,), depth * 1.05) is None  # same key, another surface: rejected
    assert (cache.hits, cache.misses, cache.rejected) == (1, 2, 1)
    # a pose whose key changed (a bin edge) is found by its surface, and refiled
    assert cache.get((9,), depth * 1.201) is entries[2]
    assert cache.found_by_surface == 1 and cache.get((9,), depth * 1.2) is entries[2]
    assert len(cache) == 1
    o = np.array([0.0, 0.0, 0.0])
    assert pose_key(o, depth, 0.03, 0.03) != pose_key(o + 0.05, depth, 0.03, 0.03)
    assert pose_key(o, depth, 0.03, 0.03) != pose_key(o, depth + 0.1, 0.03, 0.03)


def test_entries_from_fewer_averaged_frames_are_passed_over_but_kept() -> None:
    depth = np.full((21, 21), 1.5)
    cache: PoseCache[_Entry] = PoseCache(4)
    single = _Entry(depth, frames=1)
    cache.put((1,), single)
    assert cache.get((1,), depth, min_frames=3) is None
    assert len(cache) == 1 and cache.get((1,), depth, min_frames=1) is single


def test_nearest_finds_an_entry_of_the_surface_without_counting_or_moving_it() -> None:
    depth = np.full((21, 21), 1.5)
    cache: PoseCache[_Entry] = PoseCache(4)
    near, far = _Entry(depth * 1.001, frames=3), _Entry(depth * 1.3, frames=3)
    young = _Entry(depth, frames=1)
    for k, e in enumerate((near, far, young)):
        cache.put((k,), e)
    assert cache.nearest(depth, min_frames=2) is near  # the single-frame one passed over
    assert cache.nearest(depth) is young  # the most recent that fits
    assert cache.nearest(depth, accept=lambda e: e is not young) is near
    assert cache.nearest(depth * 2.0) is None
    assert (cache.hits, cache.misses, len(cache)) == (0, 0, 3)
    assert cache.get((0,), depth * 1.001) is near  # still filed where it was


def test_a_surface_turned_in_the_projector_s_frame_is_told_by_its_fitted_plane() -> None:
    """Depths within the match's percent still let a wall turned away from the device
    turn in frame P by a degree (the device turned): the fitted planes tell the turn
    (exactly for a plane: its inverse depth is linear in the normalised coordinates),
    and a move along the normal or noise of a few millimetres does not."""
    from adaproj_edge.geometry.rotations import rotation_matrix

    K = np.array([[1400.0, 0.0, 639.5], [0.0, 1400.0, 399.5], [0.0, 0.0, 1.0]])
    u, v = np.meshgrid(np.linspace(0, 1279, 21), np.linspace(0, 799, 21))
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K).T  # z = 1
    yaw = np.radians(35.0)
    n = np.array([np.sin(yaw), 0.0, np.cos(yaw)]) / 1.5  # a wall turned 35 deg, 1.5 m

    def depth(normal: FloatArray) -> FloatArray:
        out: FloatArray = 1.0 / (rays @ normal)
        return out

    points = rays * depth(n)[..., None]
    for axis in np.eye(3):
        turn = np.radians(0.6)
        turned = depth(rotation_matrix(turn * axis) @ n)
        assert surfaces_match(turned, depth(n), 0.01, 0.97)  # the depth check passes it
        found = surface_turn(points, turned)
        # a turn about the plane's normal leaves the plane as it is; otherwise the
        # angle between the normals, to the solve's rounding
        expect = np.arccos(np.clip(np.dot(rotation_matrix(turn * axis) @ n, n) / (n @ n), -1, 1))
        assert abs(found - expect) < 1e-9
    assert surface_turn(points, depth(1.1 * n)) < 1e-9  # moved along the normal
    rng = np.random.default_rng(0)
    noisy = depth(n) * (1 + rng.normal(0.0, 0.003, (21, 21)))  # 0.3 % per node
    assert surface_turn(points, noisy) < np.radians(0.15)
    line = depth(n).copy()
    line[:, :-1] = np.nan  # one column left: no plane to tell
    few = np.full_like(line, np.nan)
    few[:3, :3] = depth(n)[:3, :3]
    assert surface_turn(points, line) == np.inf and surface_turn(points, few) == np.inf


def _wall_lattice(
    kind: str, z0: float, seed: int, shift: float = 0.0, yaw_deg: float = 30.0, box: bool = False
) -> tuple[Surface, SensorModel]:
    """The runtime's lattice (frame P, walls snapped) of one depth frame the simulator
    draws from the sensor model ``kind`` (its steps, correlated noise, holes and edges)
    of a wall turned ``yaw_deg`` about the vertical, ``z0 + shift`` ahead on the depth
    camera's axis; ``box``: a box 30 cm before it, in front of part of the picture."""
    from adaproj_edge.app.surfaces import SurfaceSource
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.hal.depth import DepthFrame
    from adaproj_edge.session.stereo import StereoNoise, stereo_depth

    cal = Calibration.default()
    d = cal.depth
    v, u = np.mgrid[0 : d.height, 0 : d.width].astype(float)
    rays = np.stack([(u - d.K[0, 2]) / d.K[0, 0], (v - d.K[1, 2]) / d.K[1, 1], np.ones_like(u)], -1)
    t = np.radians(yaw_deg)
    n = np.array([np.sin(t), 0.0, -np.cos(t)])
    pts = rays * ((n @ np.array([0.0, 0.0, z0 + shift])) / (rays @ n))[..., None]
    if box:
        front = (np.abs(rays[..., 0]) < 0.15) & (np.abs(rays[..., 1] - 0.1) < 0.12)
        pts = np.where(front[..., None], rays * (z0 - 0.3), pts)
    sensor = SensorModel.of(d, kind)
    mm = stereo_depth(pts, d, StereoNoise.of_sensor(sensor), np.random.default_rng(seed), pts)
    src = SurfaceSource(cal, AppSettings(), Telemetry(10).times)
    est = src.filter.update(src.estimate(DepthFrame(0, 0, 0, mm)), still=False)
    return src.prepared(est), sensor


@pytest.mark.parametrize(("kind", "z0"), [("oak-d", 1.5), ("kinect", 4.0)])
def test_estimates_of_one_wall_agree_within_the_sensor_noise_and_a_changed_wall_does_not(
    kind: str, z0: float
) -> None:
    """Two frames of one wall (independent noise draws of the sensor model) are served
    each other's warp, also when a small hole at the frame's border is filled in one and
    not the other, or the device swayed 5 mm
    toward it; the wall moved 3 cm, turned
    1.5 degrees, or with a box in front of it, never is. The cache serves an entry when
    the depths agree (:func:`surfaces_agree`) and the fitted planes turned at most
    ``cache_turn_rad`` (:func:`surface_turn`), as the runtime checks them. At 4 m the
    relative check (1 %) served the moved wall. The runtime's cache
    (:meth:`~adaproj_edge.app.warps.WarpSource.pose`) decides the same."""
    s = AppSettings()
    then, sensor = _wall_lattice(kind, z0, 1)
    z_then = then.points[..., 2].astype(np.float64)

    def served(now: Surface) -> bool:
        z = now.points[..., 2].astype(np.float64)
        agree = surfaces_agree(
            z, z_then, (1, 1), sensor, s.cache_match_sigmas, s.cache_spread_sigmas, s.cache_overlap
        )
        return agree and surface_turn(now.points, z_then) <= s.cache_turn_rad

    same = _wall_lattice(kind, z0, 2)[0]
    assert served(same)
    points = same.points.copy()  # the estimator left a hole at the top right border unfilled
    r, c = points.shape[:2]
    points[: r // 7, -c // 7 :] = np.nan  # 2 % of the nodes (the corner replay's 5 % are not)
    holed = Surface(points, same.projector)
    assert served(holed)
    moved = _wall_lattice(kind, z0, 3, shift=0.03)[0]
    assert not served(moved)
    assert not served(_wall_lattice(kind, z0, 4, yaw_deg=31.5)[0])
    if z0 < 2.0:
        assert not served(_wall_lattice(kind, z0, 5, box=True)[0])
        assert served(_wall_lattice(kind, z0, 6, shift=0.005)[0])  # the hand's sway
        source = WarpSource(then.projector, s, Telemetry(100), sensor=sensor)
        o, size, ws = np.zeros(3), (640, 400), WarpSettings(mode="content")
        first, hit = source.pose(then, 1, 0, o, size, ws)
        assert not hit and source.pose(holed, 1, 0, o, size, ws) == (first, True)
        assert not source.pose(moved, 1, 0, o, size, ws)[1]
