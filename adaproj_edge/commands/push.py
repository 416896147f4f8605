"""``adaproj push``: send an image or a video clip (and a mask) to the projector over
USB serial."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from adaproj_edge.errors import ImageError
from adaproj_edge.link.contentcheck import Limits, check_content
from adaproj_edge.link.store import check_name
from adaproj_edge.warp.engine import MODES

DEFAULT_PORT = "/dev/ttyACM0"


def add_port(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--port", default=DEFAULT_PORT, help="the device's serial port (default %(default)s)"
    )


def add_settings(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mode", choices=MODES, help="warp mode (device default: content)")
    p.add_argument("--threshold", type=float, help="content-map threshold in [0, 1]")


def settings_of(args: argparse.Namespace) -> dict[str, Any] | None:
    s = {k: getattr(args, k) for k in ("mode", "threshold") if getattr(args, k) is not None}
    return s or None


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "push",
        help="upload an image or a clip (and a mask) to the projector, resuming a cut transfer",
        description=(
            "Upload IMAGE (PNG or JPEG, or a video clip: MP4, AVI or MKV holding H.264, "
            "MPEG-4 or MJPEG) to the device's content store over USB serial (SMP). The "
            "file is checked here as the device will check it before a byte is sent. An "
            "interrupted transfer resumes where the device stopped; a file the device "
            "already holds is not sent again."
        ),
    )
    p.add_argument("image", type=Path, help="the content (PNG, JPEG, MP4, AVI or MKV)")
    p.add_argument("--mask", type=Path, help="user mask (PNG, white = important)")
    p.add_argument("--name", help="name on the device (default: the file's name)")
    p.add_argument("--activate", action="store_true", help="show it once uploaded")
    p.add_argument("--no-resume", action="store_true", help="always send from the start")
    add_port(p)
    add_settings(p)
    p.set_defaults(run=run)


class ProgressBar:
    """A one-line progress bar on stderr: bar, percent, bytes, rate."""

    def __init__(self, label: str, width: int = 30) -> None:
        self.label = label
        self.width = width
        self.t0 = time.monotonic()
        self.first: int | None = None

    def __call__(self, done: int, total: int) -> None:
        if self.first is None:
            self.first = done
        frac = done / total if total else 1.0
        fill = int(frac * self.width)
        dt = max(time.monotonic() - self.t0, 1e-6)
        rate = (done - self.first) / dt / 1024
        sys.stderr.write(
            f"\r{self.label} [{'#' * fill}{'.' * (self.width - fill)}] {frac:6.1%} "
            f"{done}/{total} B {rate:7.1f} KiB/s"
        )
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def local_item(path: Path, name: str | None) -> tuple[str, bytes]:
    """(device name, bytes) of a local file, checked as the device will check it."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise ImageError(f"cannot read {path}: {e.strerror or e}") from None
    device_name = check_name(name or path.name)
    check_content(path, device_name, Limits())
    return device_name, data


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.link import client

    items = [local_item(args.image, args.name)]
    if args.mask is not None:
        items.append(local_item(args.mask, None))

    async def go() -> None:
        async with client.connect(args.port) as c:
            for name, data in items:
                start = await client.upload(
                    c, data, name, ProgressBar(name), resume=not args.no_resume
                )
                if start == len(data):
                    print(f"{name}: already on the device")
                elif start:
                    print(f"{name}: resumed at byte {start}, {len(data)} bytes on the device")
                else:
                    print(f"{name}: {len(data)} bytes on the device")
            if args.activate:
                mask = items[1][0] if len(items) > 1 else None
                req = client.ActivateWrite(image=items[0][0], mask=mask, settings=settings_of(args))
                r = await client.call(c, req)
                print(f"showing {r.active['image']}")

    client.run(go())
    return 0
