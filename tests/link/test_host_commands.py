"""``adaproj push`` and ``adaproj device`` on the rough paths: what they say and keep.

Each test runs the real command (through ``adaproj_edge.cli.main``, or as a process
where what reaches the terminal matters) against the device's server on a pty.
"""

from __future__ import annotations

import asyncio
import io
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from adaproj_edge import cli
from adaproj_edge.commands.push import ProgressBar
from adaproj_edge.errors import LinkError
from adaproj_edge.hal.serial import PtyPair
from adaproj_edge.link import client
from adaproj_edge.link.host_requests import ActivateWrite
from tests.link.conftest import NoisyLine, Running
from tests.link.media import png_bytes
from tests.link.noise import Damage
from tests.link.test_pty_clients import ENV


def files(tmp_path: Path, **images: bytes) -> dict[str, str]:
    """Write each image to ``tmp_path`` under its name (``_`` for ``.``); their paths."""
    out = {}
    for key, data in images.items():
        p = tmp_path / key.replace("_", ".")
        p.write_bytes(data)
        out[key] = str(p)
    return out


def test_activate_keeps_the_shown_mask_unless_told(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = files(
        tmp_path,
        wall_png=png_bytes(160, 100, seed=1),
        wall_mask_png=png_bytes(160, 100, seed=2),
        other_png=png_bytes(160, 100, seed=3),
    )
    port = ["--port", running.pty.path]
    assert cli.main(["push", f["wall_png"], "--mask", f["wall_mask_png"], "--activate", *port]) == 0
    assert cli.main(["device", "activate", "wall.png", "--mode", "conformal", *port]) == 0
    active = running.store.active()
    assert active is not None and active.mask == "wall.mask.png"
    assert active.settings["mode"] == "conformal"
    assert "with mask wall.mask.png" in capsys.readouterr().out

    assert cli.main(["device", "activate", "wall.png", "--no-mask", *port]) == 0
    active = running.store.active()
    assert active is not None and active.mask is None
    assert "(no mask)" in capsys.readouterr().out

    assert cli.main(["device", "activate", "wall.png", "--mask", "wall.mask.png", *port]) == 0
    assert cli.main(["push", f["other_png"], "--activate", *port]) == 0  # another image
    active = running.store.active()
    assert active is not None and (active.image, active.mask) == ("other.png", None)

    assert cli.main(["device", "activate", "x.png", "--mask", "m.png", "--no-mask", *port]) == 2
    assert "contradict" in capsys.readouterr().err


def test_list_prints_sizes_for_people(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = png_bytes(160, 100, seed=4)
    f = files(tmp_path, poster_png=data)
    assert cli.main(["push", f["poster_png"], "--activate", "--port", running.pty.path]) == 0
    capsys.readouterr()
    assert cli.main(["device", "list", "--port", running.pty.path]) == 0
    out = capsys.readouterr().out
    row = next(x for x in out.splitlines() if "poster.png" in x and x.startswith("*"))
    assert f"{len(data) / 1024:.1f} KiB" in row and "160x100" in row
    assert str(len(data)) not in out  # no raw byte counts
    assert "of 4.0 MiB" in out  # the fixture's quota


def test_probes_are_not_errors_in_the_status(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = files(tmp_path, a_png=png_bytes(100, 80, seed=5))
    assert cli.main(["push", f["a_png"], "--port", running.pty.path]) == 0
    assert running.server.counters["probes"] >= 1  # "is a.png there yet?": no
    assert running.server.counters["errors"] == 0


def test_an_error_after_the_bar_starts_on_a_line_of_its_own(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = files(tmp_path, big_png=png_bytes(1300, 1100, seed=6))  # more than the 4 MiB quota
    assert Path(f["big_png"]).stat().st_size > 4 * 2**20
    assert cli.main(["push", f["big_png"], "--port", running.pty.path]) == 2
    err = capsys.readouterr().err
    assert "big.png [" in err  # the bar was drawn
    error_line = next(x for x in err.splitlines() if "error:" in x)
    assert error_line.startswith("adaproj push: error: ") and "does not fit" in error_line


def test_no_answer_says_how_long_it_waited(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = files(tmp_path, a_png=png_bytes(60, 40, seed=7))
    with PtyPair.open() as pty:  # nothing serves the other end
        t0 = time.monotonic()
        assert cli.main(["push", f["a_png"], "--port", pty.path, "--timeout", "2"]) == 2
        waited = time.monotonic() - t0
    err = capsys.readouterr().err
    said = re.search(r"no answer from the device on \S+ within (\d+) s \((\d+) tries\)", err)
    assert said, err
    assert abs(int(said.group(1)) - waited) <= 1.5 and int(said.group(2)) >= 2


def test_a_mask_of_another_aspect_is_refused_before_anything_is_sent(
    running: Running, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = files(
        tmp_path, photo_png=png_bytes(160, 100, seed=8), square_png=png_bytes(100, 100, seed=9)
    )
    argv = ["push", f["photo_png"], "--mask", f["square_png"], "--activate"]
    assert cli.main([*argv, "--port", running.pty.path]) == 2
    err = capsys.readouterr().err
    assert "aspect" in err and "square.png" in err
    assert running.server.counters["requests"] == 0  # not even connected
    assert running.store.items() == [] and running.store.pending() == []


def test_the_device_refuses_a_mask_that_does_not_fit_too(running: Running) -> None:
    async def go() -> None:
        async with client.connect(running.pty.path) as c:
            await client.upload(c, png_bytes(160, 100, seed=10), "p.png")
            await client.upload(c, png_bytes(100, 100, seed=11), "sq.png")
            with pytest.raises(LinkError, match=r"mask sq\.png"):
                await client.call(c, ActivateWrite(image="p.png", mask="sq.png"))

    asyncio.run(go())
    assert running.store.active() is None  # nothing shown with it


def test_progress_bar_lines() -> None:
    out = io.StringIO()
    bar = ProgressBar("x.png", width=10, stream=out)
    bar(2048, 4096)
    bar.note("x.png: something happened")
    bar(3072, 4096)
    bar.close()
    bar.close()
    bar(4096, 4096)
    lines = out.getvalue().split("\n")
    assert lines[1] == "x.png: something happened"
    assert "2.0 KiB of 4.0 KiB" in lines[0] and "3.0 KiB of 4.0 KiB" in lines[2]
    assert "100.0%" in lines[3] and lines[4] == ""  # each bar line finished once


def test_push_through_noise_as_a_process_prints_short_lines(
    line: NoisyLine, tmp_path: Path
) -> None:
    """Real stderr, real logging: no frame dumps, whatever the libraries log."""
    data = png_bytes(150, 110, seed=12)
    f = files(tmp_path, photo_png=data)
    line.port.rx.plan = [Damage(6, flip_at=300)]
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "adaproj_edge.cli",
            "push",
            f["photo_png"],
            *("--port", line.pty.path),
            *("--timeout", "1"),
        ],
        capture_output=True,
        text=True,
        env=ENV,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert line.port.rx.done and (line.server.store.root / "photo.png").read_bytes() == data
    lines = proc.stderr.replace("\r", "\n").splitlines()
    assert max(map(len, lines)) < 300, "a dump on stderr"
    assert any("no answer" in x and "reconnecting" in x for x in lines)
