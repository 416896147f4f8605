"""A command that needs an extra the install lacks says which, in one line, exit 2
(adaproj_edge/extras.py): the host tools for ``push`` / ``device``, NVIDIA Warp's BVH for
casting a mesh beyond what brute force does in seconds."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.content.builtin import poster
from adaproj_edge.fileio import write_png
from adaproj_edge.geometry.mesh_surface import MAX_BRUTE_FORCE_PAIRS, MeshSurface
from adaproj_edge.progress import Progress


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def without(monkeypatch: pytest.MonkeyPatch, module: str, *users: str) -> None:
    """Make ``import module`` fail as in an install without it (and forget the package's
    modules that imported it, so that they import it again)."""
    monkeypatch.setitem(sys.modules, module, None)
    for name in users:
        if name in sys.modules:
            monkeypatch.delitem(sys.modules, name)
            parent, _, child = name.rpartition(".")
            monkeypatch.delattr(sys.modules[parent], child, raising=False)


HOST_USERS = ("adaproj_edge.link.client", "adaproj_edge.link.connection")
HOST_LINE = "needs the host tools (smpclient): pip install 'adaproj-edge[host]'"


def test_push_without_the_host_extra_names_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    without(monkeypatch, "smpclient", *HOST_USERS)
    image = tmp_path / "p.png"
    write_png(image, poster((160, 100)))
    assert main(["push", str(image), "--port", str(tmp_path / "nope")]) == 2
    assert error_line(capsys) == f"adaproj push {HOST_LINE}"


def test_device_without_the_host_extra_names_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    without(monkeypatch, "smpclient", *HOST_USERS)
    assert main(["device", "list", "--port", str(tmp_path / "nope")]) == 2
    assert error_line(capsys) == f"adaproj device {HOST_LINE}"


def flat_mesh(path: Path, n: int) -> None:
    """An ASCII .ply: a 4 m square 2 m ahead, as 2 (n-1)^2 triangles."""
    x, y = np.meshgrid(np.linspace(-2, 2, n), np.linspace(-2, 2, n))
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {n * n}",
        *(f"property float {c}" for c in "xyz"),
        f"element face {len(faces)}",
        "property list uchar int vertex_indices",
        "end_header",
        *(f"{p} {q} 2.0" for p, q in zip(x.ravel(), y.ravel(), strict=True)),
        *(f"3 {p} {q} {r}" for p, q, r in faces),
    ]
    path.write_text("\n".join(lines) + "\n")


def test_a_session_on_a_mesh_without_the_sim_extra_is_refused_at_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    without(monkeypatch, "warp", "adaproj_edge.geometry.mesh_bvh")
    mesh = tmp_path / "room.ply"
    flat_mesh(mesh, 12)  # 242 triangles x a depth frame's 256,000 rays: past the budget
    out = tmp_path / "s.mcap"
    argv = ["simulate-session", "--surface", str(mesh), "--seconds", "1", "--out", str(out)]
    assert main(argv) == 2
    line = error_line(capsys)
    assert line.startswith("adaproj simulate-session needs NVIDIA Warp's BVH ray caster")
    assert "256000 rays against 242 triangles" in line
    assert line.endswith("pip install 'adaproj-edge[sim]'")
    assert not out.exists()


def test_small_casts_without_the_sim_extra_go_on_by_brute_force(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    without(monkeypatch, "warp", "adaproj_edge.geometry.mesh_bvh")
    v = np.array([[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0]])
    mesh = MeshSurface("tri", v, np.array([[0, 1, 2]]))
    dirs = np.array([[0.0, 0.0, 1.0], [5.0, 0.0, 1.0]])
    t = mesh.intersect(np.zeros(3), dirs)
    assert t[0] == pytest.approx(2.0) and np.isnan(t[1])
    assert len(dirs) * 1 < MAX_BRUTE_FORCE_PAIRS


def test_progress_speaks_only_after_its_interval(caplog: pytest.LogCaptureFixture) -> None:
    now = [0.0]
    log = logging.getLogger("tests.progress")
    progress = Progress("frames", 10, log, every_s=3.0, clock=lambda: now[0])
    with caplog.at_level(logging.INFO, logger="tests.progress"):
        for k in range(10):
            now[0] = k * 1.0
            progress.step(k)
    assert [r.getMessage() for r in caplog.records] == [
        "frames: 3 of 10 (30 %)",
        "frames: 6 of 10 (60 %)",
        "frames: 9 of 10 (90 %)",
    ]
