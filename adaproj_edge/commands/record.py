"""``adaproj record``: record a session from the device's sensors (on the board)."""

from __future__ import annotations

import argparse
import logging
import signal
from typing import Any

from adaproj_edge.commands._outputs import check_output_file

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "record",
        help="record a session (depth, IMU, button) to an MCAP file on the device",
        description="Record every sensor of the board into one MCAP session file. "
        "Stops after --seconds, or on Ctrl-C / SIGTERM; a recording cut by power loss "
        "still replays up to the last second.",
    )
    p.add_argument("--board", default="rpi5-oakd", help="board name or board TOML file")
    p.add_argument("--out", required=True, help="session file to write (.mcap)")
    p.add_argument("--seconds", type=float, default=None, help="stop after this long")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.hal.board import Board
    from adaproj_edge.hal.button import EvdevButton
    from adaproj_edge.hal.clock import MonotonicClock
    from adaproj_edge.hal.depth import OakDepthCamera
    from adaproj_edge.hal.lsm6dsox import Lsm6dsox, open_i2c
    from adaproj_edge.session.recorder import Recorder
    from adaproj_edge.session.writer import SessionWriter

    board = Board.load(args.board)
    check_output_file(args.out, "session file")
    clock = MonotonicClock()
    calibration = board.calibration()
    # the quick checks first: a missing IMU or button is reported before the OAK-D boots
    bus = open_i2c(board.imu.bus)
    imu = Lsm6dsox(bus, clock, board.imu.address, board.imu.config, f"/dev/i2c-{board.imu.bus}")
    imu.start()
    button = EvdevButton(board.button_device, board.key_code, clock)
    depth = OakDepthCamera(board.depth, clock)
    calibration = calibration.with_depth(depth.model)
    meta = {"source": "device", "board": board.name}
    writer = SessionWriter(args.out, calibration, meta, clock.now_ns())
    rec = Recorder(writer, clock)
    signal.signal(signal.SIGTERM, lambda *_: rec.stop())

    def read_imu() -> Any:
        s = imu.read()
        if s is None:
            clock.sleep_until(clock.now_ns() + int(0.5e9 / board.imu.config.rate_hz))
        return s

    try:
        n = rec.run(
            {"depth": depth.read, "imu": read_imu, "button": lambda: button.read(0.1)},
            args.seconds,
        )
    except KeyboardInterrupt:
        n = writer.count
    finally:
        depth.close()
        imu.stop()
        imu.close()
        button.close()
    log.info("recorded %d records to %s", n, args.out)
    return 0
