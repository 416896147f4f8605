"""The product installs anywhere (issue 10) and a fresh checkout's first run says what
it does (issue 12, item 9).

- The wheel built from the checkout, installed with the ``device`` extra into a fresh
  virtual environment outside the checkout (no system site-packages), runs the built-in
  replay, a warp, a content map and the runtime's start-up checks, from a folder
  outside the checkout: everything it needs is declared and shipped.
- ``tools/adaproj`` on a fresh machine creates the environment with a line per stage,
  pip's own progress and the time it took, and no setuptools warnings.

Both install real packages (from pip's cache when it has them). The wheel's venv takes the
distributions of its resolution that this environment holds as hard links (see
``installed``), so it costs seconds rather than minutes.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from adaproj_edge.content.builtin import poster
from adaproj_edge.fileio import write_png

REPO = Path(__file__).resolve().parents[2]
SETUPTOOLS_WARNINGS = ("SetuptoolsDeprecationWarning", "SetuptoolsWarning", "!!\n")
SKIP_IN_COPY = shutil.ignore_patterns(
    ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".*_cache", ".hypothesis"
)


def clean_env(**extra: str) -> dict[str, str]:
    """This process's environment without anything that would reach into the checkout."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(extra)
    return env


def run(argv: list[str | Path], cwd: Path, **extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(a) for a in argv], cwd=cwd, env=clean_env(**extra), capture_output=True, text=True
    )


def check(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode == 0, f"{proc.args}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A fresh venv, outside the checkout, holding the wheel with the device extra.

    pip resolves the wheel's declared requirements (with the ``device`` extra) against the
    package index for the empty venv; the distributions of that resolution which this
    environment already holds at the same version are hard-linked in (their files as
    their RECORD lists them: the same files pip would unpack from the same wheels,
    without writing hundreds of MB again); pip then installs the wheel and whatever else
    the resolution needs, and finds the linked ones satisfied. The venv holds exactly
    what the resolution names and nothing of this environment besides, so an undeclared
    requirement still fails. Removed at the end of the module (pytest keeps the last
    three base temporaries, which made its own clean-up slow).
    """
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"  # build from a copy: the build leaves build/ and egg-info behind
    shutil.copytree(REPO, src, symlinks=True, ignore=SKIP_IN_COPY)
    dist = tmp / "dist"
    built = check_build(
        run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", dist, src], tmp)
    )
    assert not any(w in built for w in SETUPTOOLS_WARNINGS), built
    wheels = list(dist.glob("adaproj_edge-*.whl"))
    assert len(wheels) == 1
    venv = tmp / "venv"
    check(run([sys.executable, "-m", "venv", "--without-pip", venv], tmp))
    # the running pip, acting on the venv (which needs no pip of its own)
    pip = [sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "install"]
    pip += ["--no-compile", "--disable-pip-version-check"]
    wanted = f"{wheels[0]}[device]"
    report = tmp / "resolution.json"
    check(run([*pip, "--dry-run", "--report", report, wanted], tmp))
    resolved = json.loads(report.read_text())["install"]
    site = next(venv.glob("lib/python*/site-packages"))
    link_distributions(resolved, site)
    check(run([*pip, wanted], tmp))
    held = {canonical(d.name.split("-")[0]) for d in site.glob("*.dist-info")}
    assert held == {canonical(item["metadata"]["name"]) for item in resolved}
    yield venv
    shutil.rmtree(tmp, ignore_errors=True)


def link_distributions(resolved: list[dict[str, Any]], site: Path) -> list[str]:
    """Hard-link into ``site`` each resolved distribution this environment holds.

    Parameters
    ----------
    resolved : list of dict
        The ``install`` entries of a pip installation report.
    site : Path
        The target venv's site-packages.

    Returns
    -------
    list of str
        The names of the distributions linked: those held here at the resolved version
        (not adaproj-edge itself), each with every file its RECORD lists under
        site-packages (console scripts, outside it, are not needed by the tests).
    """
    linked = []
    for item in resolved:
        name, version = item["metadata"]["name"], item["metadata"]["version"]
        if canonical(name) == "adaproj-edge":
            continue
        try:
            held = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        if held.version != version or not held.files:
            continue
        root = Path(str(held.locate_file(""))).resolve()
        for rel in held.files:
            src = Path(str(held.locate_file(rel))).resolve()
            if root not in src.parents or not src.is_file():
                continue  # a script in bin/, or a file RECORD lists that is not there
            dst = site / src.relative_to(root)
            dst.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.link(src, dst)
            except OSError:  # another file system (or no hard links there): a copy
                shutil.copy2(src, dst)
        linked.append(name)
    return linked


def canonical(name: str) -> str:
    """A distribution name as pip compares them (PEP 503)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def check_build(proc: subprocess.CompletedProcess[str]) -> str:
    check(proc)
    return proc.stdout + proc.stderr


@pytest.fixture(scope="module")
def work(installed: Path) -> Path:
    """A folder outside the checkout with the built-in poster as a PNG."""
    d = installed.parent / "work"
    d.mkdir()
    write_png(d / "poster.png", poster())
    return d


@pytest.mark.slow
def test_the_wheel_holds_the_package_and_its_files_but_no_tests(installed: Path) -> None:
    wheel = next((installed.parent / "dist").glob("*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for shipped in (
        "adaproj_edge/py.typed",
        "adaproj_edge/data/cylinder.mcap",
        "adaproj_edge/hw/boards/rpi5-oakd.toml",
        "adaproj_edge/hw/calibration/rpi5-oakd.toml",
        "adaproj_edge/models/gbvs_saliency.onnx",
        "adaproj_edge/threads.py",
    ):
        assert shipped in names, shipped
    assert not any(n.startswith("tests/") for n in names)


@pytest.mark.slow
def test_the_installed_package_is_the_one_used(installed: Path, work: Path) -> None:
    code = "import adaproj_edge, depthai, smbus2; print(adaproj_edge.__file__)"
    out = check(run([installed / "bin" / "python", "-c", code], work))
    where = Path(out.strip().splitlines()[-1])  # (depthai may print a warning first)
    assert installed in where.parents and REPO not in where.parents


@pytest.mark.slow
def test_replay_of_the_built_in_session(installed: Path, work: Path) -> None:
    out = check(run([installed / "bin" / "adaproj", "replay", "--out", "replay"], work))
    assert "cylinder.mcap" in out
    summary = json.loads((work / "replay" / "summary.json").read_text())
    assert summary["counters"]["frames_shown"] > 0
    assert (work / "replay" / "contact_sheet.png").stat().st_size > 0


@pytest.mark.slow
def test_warp_on_a_built_in_surface(installed: Path, work: Path) -> None:
    argv = ["warp", "--surface", "sphere-convex", "--image", "poster.png", "--out", "W.npz"]
    report = json.loads(check(run([installed / "bin" / "adaproj", *argv], work)))
    assert report["mode"] == "content" and report["iterations"] > 0
    assert (work / "W.npz").stat().st_size > 0


@pytest.mark.slow
def test_saliency_with_the_shipped_model(installed: Path, work: Path) -> None:
    argv = ["saliency", "poster.png", "--out", "M.png"]
    assert "salient" in check(run([installed / "bin" / "adaproj", *argv], work))
    assert (work / "M.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.slow
def test_run_start_up_checks(installed: Path, work: Path) -> None:
    adaproj = installed / "bin" / "adaproj"
    # no projector hardware here: the report, and exit status 1 for the missing devices
    proc = run([adaproj, "run", "--board", "rpi5-oakd", "--check"], work)
    assert proc.returncode == 1, proc.stderr
    out = proc.stdout
    assert out.splitlines()[-1].endswith("`adaproj doctor` says what to do")
    site = next(installed.glob("lib/python*/site-packages"))
    cal = site / "adaproj_edge" / "hw" / "calibration" / "rpi5-oakd.toml"
    assert f"board rpi5-oakd, calibration {cal}" in out.splitlines()[0]
    assert "projector 1280x800" in out
    # without the projector's hardware: the board and calibration load, then one line
    argv = ["run", "--board", "rpi5-oakd", "--store", "store", "--state", "state"]
    proc = run([adaproj, *argv], work)
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    # the journal's INFO lines (the calibration in use), then one error line
    assert err[-1].startswith("adaproj run: error: "), err
    assert all(line.startswith("INFO ") for line in err[:-1]), err
    assert any("calibration: " in line for line in err[:-1]), err
    assert "check that" in err[-1]  # says what to check (the framebuffer, a device)


@pytest.fixture
def fresh_venv(tmp_path: Path) -> Iterator[Path]:
    """Where ``tools/adaproj`` is to create its environment; removed after the test
    (pytest keeps the last three base temporaries)."""
    yield tmp_path / "venv"
    shutil.rmtree(tmp_path / "venv", ignore_errors=True)


@pytest.mark.slow
def test_first_run_shows_its_progress(tmp_path: Path, fresh_venv: Path) -> None:
    venv = fresh_venv
    proc = run([REPO / "tools" / "adaproj", "--help"], tmp_path, ADAPROJ_VENV=str(venv))
    out = check(proc)
    assert "usage: adaproj" in out
    err = proc.stderr
    stages = [line for line in err.splitlines() if line.startswith("adaproj: [")]
    assert [s[:14] for s in stages] == ["adaproj: [1/3]", "adaproj: [2/3]", "adaproj: [3/3]"]
    assert "Successfully installed" in err  # pip's own progress, not --quiet
    assert f"adaproj: {venv} ready in " in err
    assert not any(w in err for w in SETUPTOOLS_WARNINGS), err
    # the second run installs nothing and says nothing
    again = run([REPO / "tools" / "adaproj", "--help"], tmp_path, ADAPROJ_VENV=str(venv))
    assert check(again) == out and again.stderr == ""
