"""``adaproj link``: the device side of the USB link (the SMP server) on its own."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

from adaproj_edge.errors import InputError
from adaproj_edge.hal.serial import DEVICE_PORT, FdPort, PySerialPort, SerialPort
from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.ids import BUF_SIZE
from adaproj_edge.link.server import Server, serve
from adaproj_edge.link.store import ContentStore, Limits

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "link",
        help="run the SMP server (content updates over USB serial) on its own",
        description=(
            "Serve the SMP (MCUmgr) OS, file-system and adaproj groups on a serial port, "
            "storing content in DIR. Without the projector pipeline the active image is "
            "shown letterboxed. For bring-up, tests and benchmarks; the device runtime "
            "runs the same server."
        ),
    )
    p.add_argument("--port", default=DEVICE_PORT, help="serial port (default %(default)s)")
    p.add_argument(
        "--fd",
        type=int,
        help="serve on this inherited file descriptor instead of --port (a pty master)",
    )
    p.add_argument("--store", type=Path, required=True, metavar="DIR", help="content store")
    p.add_argument(
        "--buf-size",
        type=int,
        default=BUF_SIZE,
        help="SMP buffer advertised to clients, bytes (default %(default)s)",
    )
    p.add_argument(
        "--quota-mb", type=float, default=Limits.quota / 2**20, help="store quota in MiB"
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if not 64 <= args.buf_size <= 0xFFFF:
        raise InputError(f"--buf-size must be in 64..65535, not {args.buf_size}")
    if args.quota_mb <= 0:
        raise InputError(f"--quota-mb must be positive, not {args.quota_mb}")
    store = ContentStore(args.store, Limits(quota=int(args.quota_mb * 2**20)))
    server = Server(store, StandaloneDevice(), buf_size=args.buf_size)
    server.on_reset = server.restore_active
    port: SerialPort = FdPort(args.fd) if args.fd is not None else PySerialPort(args.port)
    where = f"fd {args.fd}" if args.fd is not None else args.port
    log.info("serving %s on %s", args.store, where)
    try:
        serve(port, server)
    finally:
        port.close()
    return 0
