"""The thread policy is in force inside a command, whatever the caller's environment
says (issue 12, item 1): a command run with the BLAS/OpenMP/OpenCV variables set to many
threads computes with one (or ``ADAPROJ_THREADS``), as ``adaproj -v`` reports from
``threadpoolctl``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import pytest
import threadpoolctl

from adaproj_edge.cli import main
from adaproj_edge.content.builtin import poster
from adaproj_edge.render import project as project_module
from adaproj_edge.threads import LIBRARY_ENV, THREADS_ENV

MANY = "2"  # what a caller might set; this machine has at least 2 cores (checked below)


def hostile_env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != THREADS_ENV}
    env.update({name: MANY for name in LIBRARY_ENV})
    env.update(extra)
    return env


def threads_in_command(tmp_path: Path, env: dict[str, str]) -> dict[str, Any]:
    image = tmp_path / "img.png"
    cv2.imwrite(str(image), poster((160, 100)))
    argv = [sys.executable, "-m", "adaproj_edge", "-v", "warp", "--surface", "plane"]
    argv += ["--image", str(image), "--out", str(tmp_path / "w.npz")]
    argv += ["--mode", "conformal", "--grid", "4x4"]
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    line = next(x for x in proc.stderr.splitlines() if "adaproj_edge.cli: threads: " in x)
    report: dict[str, Any] = json.loads(line.split("threads: ", 1)[1])
    return report


def test_machine_has_cores_to_spare() -> None:
    assert (os.cpu_count() or 1) >= int(MANY)


def test_one_thread_by_default_whatever_the_environment_says(tmp_path: Path) -> None:
    report = threads_in_command(tmp_path, hostile_env())
    assert report == {"policy": 1, "openblas": 1, "opencv": 1}


def test_adaproj_threads_sets_the_count(tmp_path: Path) -> None:
    env = hostile_env(OPENBLAS_NUM_THREADS="1", OPENCV_FOR_THREADS_NUM="1")
    env[THREADS_ENV] = "2"
    assert threads_in_command(tmp_path, env) == {"policy": 2, "openblas": 2, "opencv": 2}


def test_without_the_policy_the_environment_would_win(tmp_path: Path) -> None:
    # the control: the same command with the policy off shows the caller's threads, so
    # the two tests above would fail if the policy were not applied
    report = threads_in_command(tmp_path, hostile_env(**{THREADS_ENV: "auto"}))
    assert report == {"policy": None, "openblas": int(MANY), "opencv": int(MANY)}


def test_policy_in_force_inside_a_command_in_this_process(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # numpy, scipy and OpenCV are loaded already here: threadpoolctl does the work
    seen: list[list[dict[str, Any]]] = []
    real = project_module.show

    def spy(*args: Any, **kwargs: Any) -> Any:
        seen.append(threadpoolctl.threadpool_info())
        seen[-1].append({"user_api": "opencv", "num_threads": cv2.getNumThreads()})
        return real(*args, **kwargs)

    monkeypatch.setattr(project_module, "show", spy)
    monkeypatch.delenv(THREADS_ENV, raising=False)
    image = tmp_path / "img.png"
    cv2.imwrite(str(image), poster((160, 100)))
    with threadpoolctl.threadpool_limits():  # restore this process's limits afterwards
        threadpoolctl.threadpool_limits(limits=int(MANY))
        cv2.setNumThreads(int(MANY))
        argv = ["warp", "--surface", "plane", "--image", str(image), "--mode", "conformal"]
        assert main([*argv, "--grid", "4x4", "--out", str(tmp_path / "w.npz")]) == 0
    assert len(seen) == 1
    assert {lib["user_api"] for lib in seen[0]} >= {"blas", "opencv"}
    assert all(lib["num_threads"] == 1 for lib in seen[0])


UNITS = sorted((Path(__file__).resolve().parents[2] / "hw" / "systemd").glob("*.service"))


@pytest.mark.parametrize("path", UNITS, ids=lambda p: p.name)
def test_units_running_adaproj_state_their_thread_policy(path: Path) -> None:
    lines = [x.strip() for x in path.read_text().splitlines()]
    exec_start = next(x for x in lines if x.startswith("ExecStart="))
    env = dict(
        x.removeprefix("Environment=").split("=", 1) for x in lines if x.startswith("Environment=")
    )
    runs_adaproj = Path(exec_start.split()[0].removeprefix("ExecStart=")).name == "adaproj"
    assert (THREADS_ENV in env) == runs_adaproj
    assert env.get(THREADS_ENV, "1") == "1"  # the default, stated where it applies
