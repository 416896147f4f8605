"""The systemd units in hw/systemd cannot drift from the CLI: every ``adaproj`` command
line they run parses, flag by flag (spelled out, no abbreviation), with the real
parser; the runtime's unit conflicts with the link's and can open its devices."""

from __future__ import annotations

import argparse
import configparser
import shlex
from pathlib import Path

import pytest

from adaproj_edge.cli import build_parser
from adaproj_edge.hal.board import Board

HW = Path(__file__).resolve().parents[2] / "hw"
UNITS = sorted((HW / "systemd").glob("*.service"))


def unit(path: Path) -> configparser.ConfigParser:
    p = configparser.ConfigParser(strict=False, interpolation=None)
    p.optionxform = str  # type: ignore[assignment,method-assign]
    p.read(path)
    return p


def adaproj_argv(path: Path) -> list[str] | None:
    """The arguments after the ``adaproj`` binary in the unit's ExecStart (None: not ours)."""
    argv = shlex.split(unit(path)["Service"]["ExecStart"].lstrip("-@:+!"))
    if not argv or Path(argv[0]).name != "adaproj":
        return None
    return argv[1:]


def _subcommand(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            sub = action.choices.get(name)
            assert sub is not None, f"no command {name!r}"
            return sub
    raise AssertionError("the CLI has no subcommands")


def test_there_are_units_running_adaproj() -> None:
    names = {p.name for p in UNITS if adaproj_argv(p) is not None}
    assert {"adaproj.service", "adaproj-link.service"} <= names


@pytest.mark.parametrize(
    "path", [p for p in UNITS if adaproj_argv(p) is not None], ids=lambda p: p.name
)
def test_exec_start_flags_exist_in_the_cli(path: Path) -> None:
    argv = adaproj_argv(path)
    assert argv is not None
    parser = build_parser()
    args = parser.parse_args(argv)  # exits (fails the test) on anything unknown
    known = set(_subcommand(parser, argv[0])._option_string_actions)
    flags = [a.split("=", 1)[0] for a in argv[1:] if a.startswith("-")]
    assert flags and all(f in known for f in flags), (flags, sorted(known))
    if argv[0] == "run":
        Board.load(args.board)  # the board it names is in hw/boards


def test_runtime_unit_conflicts_with_the_link_unit_and_restarts() -> None:
    u = unit(HW / "systemd" / "adaproj.service")
    assert "adaproj-link.service" in u["Unit"]["Conflicts"].split()
    assert "serial-getty@ttyGS0.service" in u["Unit"]["Conflicts"].split()
    assert (
        "adaproj.service"
        in unit(HW / "systemd" / "adaproj-link.service")["Unit"]["Conflicts"].split()
    )
    assert u["Service"]["Restart"] in ("always", "on-failure")
    assert float(u["Service"]["RestartSec"]) > 0
    argv = adaproj_argv(HW / "systemd" / "adaproj.service")
    assert argv is not None and argv[0] == "run"
    for flag in ("--board", "--store", "--state"):
        assert flag in argv
    # the store and state directories are the unit's own state directories
    states = {f"/var/lib/{d}" for d in u["Service"]["StateDirectory"].split()}
    assert argv[argv.index("--store") + 1] in states
    assert argv[argv.index("--state") + 1] in states


def test_runtime_unit_can_open_its_devices() -> None:
    u = unit(HW / "systemd" / "adaproj.service")
    assert u["Service"]["User"] == "adaproj"
    groups = set(u["Service"]["SupplementaryGroups"].split())
    # I2C (IMU), framebuffer, input (button), the serial link, the OAK-D
    assert {"i2c", "video", "input", "dialout", "plugdev"} <= groups
    link_rule = (HW / "udev" / "90-adaproj-link.rules").read_text()
    assert 'KERNEL=="ttyGS0", GROUP="dialout"' in link_rule
    oak_rule = (HW / "udev" / "80-adaproj-oakd.rules").read_text()
    assert 'ATTRS{idVendor}=="03e7"' in oak_rule and 'GROUP="plugdev"' in oak_rule
    board = Board.load("rpi5-oakd")
    assert board.display_device == "/dev/fb0" and board.serial_device == "/dev/ttyGS0"
