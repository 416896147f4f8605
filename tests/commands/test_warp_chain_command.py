"""``adaproj warp`` goes down the same warp chain as the device and says where it ended:
a floor with a flying pixel is repaired, a third of it flying gives the keystone, and
both write a picture."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.content.builtin import poster
from adaproj_edge.geometry.analytic import Plane, ray_cast
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.warpmap import Grid

P = Projector.default()
PITCH = np.deg2rad(50.0)
FLOOR = Plane("floor", (0.0, -float(np.cos(PITCH)), -float(np.sin(PITCH))), -1.2)


def _floor(flying: float) -> Surface:
    """The floor on the default grid's lattice: its second border node a flying pixel,
    and ``flying`` of the other nodes too."""
    pts = ray_cast(FLOOR, np.zeros(3), P.rays(Grid().vertices(P)))
    rng = np.random.default_rng(0)
    fly = rng.random(pts.shape[:2]) < flying
    fly[0, 1] = True
    pts[fly] *= rng.uniform(0.3, 0.7, (int(fly.sum()), 1))
    return Surface(pts.astype(np.float32), P)


@pytest.mark.parametrize(("flying", "step"), [(0.0, "repaired"), (0.3, "keystone")])
def test_the_cli_prints_the_step_it_ended_at(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flying: float, step: str
) -> None:
    _floor(flying).save(tmp_path / "s.npz")
    cv2.imwrite(str(tmp_path / "img.png"), poster((320, 200)))
    cmap = np.zeros((100, 160), np.uint8)
    cmap[30:70, 50:110] = 255
    cv2.imwrite(str(tmp_path / "c.png"), cmap)
    rc = main(
        [
            "warp", "--surface", str(tmp_path / "s.npz"), "--image", str(tmp_path / "img.png"),
            "--content-map", str(tmp_path / "c.png"), "--out", str(tmp_path / "w.npz"),
            "--frame", str(tmp_path / "f.png"),
        ]
    )  # fmt: skip
    assert rc == 0
    report = json.loads(capsys.readouterr().out)
    assert report["step"] == step
    assert report["down"][0]["step"] == "content-aware" and report["down"][0]["reason"]
    frame = cv2.imread(str(tmp_path / "f.png"))
    assert (frame.max(axis=2) > 0).mean() > 0.3  # a picture, not a dark frame
