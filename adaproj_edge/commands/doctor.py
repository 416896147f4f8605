"""``adaproj doctor``: check the device's hardware, calibration and disk, and say what
to fix."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from adaproj_edge.resources import DEVICE_CALIBRATION

if TYPE_CHECKING:
    from adaproj_edge.app.doctor import Finding

EXIT_FAILED = 1
"""Exit status when a check failed (the report says which and what to do)."""

MARK = {"ok": "ok  ", "warn": "warn", "fail": "FAIL"}


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "doctor",
        help="check the device's hardware, calibration and disk; say what to fix",
        description="On the device: checks that DepthAI finds the OAK-D and its calibration "
        "reads, that the IMU answers on I2C (WHO_AM_I), that the projector's framebuffer "
        "opens in the calibration's mode, that the USB gadget's serial port and the "
        "button are there, the calibration file's verdict, and the free space for the "
        "content store. Prints a line per check and, for each failure, what to do; exits "
        "1 when a check failed, 0 otherwise (warnings included).",
    )
    p.add_argument("--board", default="rpi5-oakd", help="board name or board TOML file")
    p.add_argument(
        "--calibration",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help=f"calibration file (default: the one `adaproj run` uses: {DEVICE_CALIBRATION} "
        "when it exists, else the board's nominal one)",
    )
    p.add_argument(
        "--store",
        type=Path,
        default=Path("/var/lib/adaproj/content"),
        help="content store whose disk is checked (default /var/lib/adaproj/content)",
    )
    p.add_argument(
        "--root",
        type=Path,
        default=Path("/"),
        help="prefix of the /dev and /sys paths (default /; a test tree)",
    )
    p.set_defaults(run=run)


def report(findings: list[Finding]) -> list[str]:
    """The lines printed: one per check, and an indented one with the fix after each
    that did not pass, then a summary."""
    width = max(len(f.what) for f in findings)
    lines = []
    for f in findings:
        lines.append(f"{MARK[f.status]}  {f.what:<{width}}  {f.detail}")
        if f.fix:
            lines.append(f"      {'':<{width}}  -> {f.fix}")
    failed = sum(f.status == "fail" for f in findings)
    warned = sum(f.status == "warn" for f in findings)
    if failed:
        lines.append(f"{failed} of {len(findings)} checks failed")
    else:
        lines.append(
            f"all {len(findings)} checks passed" + (f" ({warned} warned)" if warned else "")
        )
    return lines


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.app.doctor import examine
    from adaproj_edge.hal.board import Board, calibration_in_use
    from adaproj_edge.hal.probes import Probes

    board = Board.load(args.board)
    calibration = calibration_in_use(board, args.calibration)
    findings = examine(board, calibration, args.store, Probes(args.root))
    for line in report(findings):
        print(line)
    return EXIT_FAILED if any(f.status == "fail" for f in findings) else 0
