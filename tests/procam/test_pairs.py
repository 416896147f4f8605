"""Point pairs from rendered captures of a wall corner, checked against the true rig's
own projection of each pair's 3D point."""

from __future__ import annotations

import numpy as np

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.procam.graycode import PatternSet, decode
from adaproj_edge.procam.pairs import Pairs, pose_pairs
from adaproj_edge.session.scene_render import CameraOptics, lit_view, render_capture
from adaproj_edge.session.simulator import Scene


def test_pairs_of_a_corner_match_the_true_projection() -> None:
    rig = Calibration.default()
    scene = Scene.load("corner")
    size = (320, 200)
    K = rig.depth.intrinsics_at(*size)
    optics = CameraOptics(supersample=2)
    view = lit_view(scene, rig, np.eye(3), np.zeros(3), K, size, optics)
    ps = PatternSet(1280, 800)
    rng = np.random.default_rng(3)
    images = [render_capture(view, ps.frame(i), optics, 8000, 400, rng) for i in range(len(ps))]
    T = rig.T_P_D
    depth = scene.points_seen(K, *size, T[:3, :3], T[:3, 3])[..., 2]  # exact depth
    pairs = pose_pairs(decode(images, ps), depth, K, pose=4)
    assert len(pairs) > 300 and np.all(pairs.pose == 4)
    # the truth: the rig projects each pair's point to its projector pixel
    pts = pairs.points @ T[:3, :3].T + T[:3, 3]
    uv = (pts @ rig.projector.K.T)[:, :2] / pts[:, 2:3]
    err = np.linalg.norm(uv - pairs.projector_uv, axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.5 and err.max() < 2.0
    # no pair straddles the crease (x = 0.13 m at z = 1.8 m in this frame)
    crease_px = rig.projector.K[0, 0] * (0.13 - 0.0) / 1.8 + rig.projector.K[0, 2]
    assert np.min(np.abs(pairs.projector_uv[:, 0] - crease_px)) > 5
    both = Pairs.concat([pairs, pairs.select(np.arange(10))])
    assert len(both) == len(pairs) + 10 and len(Pairs.concat([])) == 0
