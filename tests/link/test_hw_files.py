"""The system files in hw/ for the link: the gadget script parses, units and rules agree."""

from __future__ import annotations

import configparser
import shutil
import subprocess
from pathlib import Path

import pytest

HW = Path(__file__).resolve().parents[2] / "hw"


@pytest.mark.skipif(shutil.which("sh") is None, reason="no sh")
def test_gadget_script_parses_and_refuses_unknown_actions() -> None:
    script = HW / "gadget" / "adaproj-gadget.sh"
    assert subprocess.run(["sh", "-n", str(script)]).returncode == 0
    r = subprocess.run(["sh", str(script), "bogus"], capture_output=True, text=True)
    assert r.returncode == 2 and "usage" in r.stderr


def unit(name: str) -> configparser.ConfigParser:
    p = configparser.ConfigParser(strict=False, interpolation=None)
    p.optionxform = str  # type: ignore[assignment,method-assign]
    p.read(HW / "systemd" / name)
    return p


def test_link_unit_keeps_getty_off_and_serves_the_gadget_port() -> None:
    u = unit("adaproj-link.service")
    assert "serial-getty@ttyGS0.service" in u["Unit"]["Conflicts"]
    assert "adaproj-gadget.service" in u["Unit"]["Requires"]
    assert "link --port /dev/ttyGS0 --store" in u["Service"]["ExecStart"]
    g = unit("adaproj-gadget.service")
    assert g["Service"]["ExecStart"].endswith("adaproj-gadget.sh start")


def test_host_rule_keeps_modemmanager_off_the_port() -> None:
    rules = (HW / "udev" / "70-adaproj-host.rules").read_text()
    assert 'ENV{ID_MM_DEVICE_IGNORE}="1"' in rules
    script = (HW / "gadget" / "adaproj-gadget.sh").read_text()
    assert 'MANUFACTURER="adaproj"' in script and 'ATTRS{manufacturer}=="adaproj"' in rules
    assert "VID=0x1d6b" in script and "PID=0x0104" in script
