"""``adaproj push``: send an image or a video clip (and a mask) to the projector over
USB serial."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from adaproj_edge.errors import ImageError, InputError
from adaproj_edge.link.contentcheck import Limits, check_content
from adaproj_edge.link.store import check_name
from adaproj_edge.warp.engine import MODES

DEFAULT_PORT = "/dev/ttyACM0"
DEFAULT_TIMEOUT_S = 5.0
DEFAULT_TRIES = 5


def add_port(p: argparse.ArgumentParser) -> None:
    """``--port``, ``--timeout`` and ``--tries``: where the device is and how long to wait."""
    p.add_argument(
        "--port", default=DEFAULT_PORT, help="the device's serial port (default %(default)s)"
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=DEFAULT_TIMEOUT_S,
        metavar="S",
        help="seconds to wait for each answer from the device (default %(default)g)",
    )
    p.add_argument(
        "--tries",
        type=int,
        default=DEFAULT_TRIES,
        help="requests sent in a row without an answer before giving up "
        "(line noise; default %(default)d)",
    )


def link_options(args: argparse.Namespace) -> dict[str, Any]:
    """``timeout_s`` and ``tries`` from the options, checked; :class:`InputError` if bad."""
    if not 0 < args.timeout <= 600:
        raise InputError(f"--timeout must be in (0, 600] seconds, not {args.timeout:g}")
    if not 1 <= args.tries <= 100:
        raise InputError(f"--tries must be in 1..100, not {args.tries}")
    return {"timeout_s": float(args.timeout), "tries": int(args.tries)}


def add_settings(p: argparse.ArgumentParser) -> None:
    """``--mode``, ``--threshold`` and ``--no-mask``: how content is shown."""
    p.add_argument("--mode", choices=MODES, help="warp mode (device default: content)")
    p.add_argument("--threshold", type=float, help="content-map threshold in [0, 1]")
    p.add_argument(
        "--no-mask",
        action="store_true",
        help="show the image without a mask (by default an image that is already shown "
        "keeps its mask)",
    )


def settings_of(args: argparse.Namespace) -> dict[str, Any] | None:
    s = {k: getattr(args, k) for k in ("mode", "threshold") if getattr(args, k) is not None}
    return s or None


def human_size(n: float) -> str:
    """``n`` bytes for people: ``812 B``, ``4.0 KiB``, ``18.3 MiB``, ``1.2 GiB``."""
    for unit in ("B", "KiB", "MiB"):
        if abs(n) < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "push",
        help="upload an image or a clip (and a mask) to the projector, resuming a cut transfer",
        description=(
            "Upload IMAGE (PNG or JPEG, or a video clip: MP4, AVI or MKV holding H.264, "
            "MPEG-4 or MJPEG) to the device's content store over USB serial (SMP). The "
            "file is checked here as the device will check it before a byte is sent. An "
            "interrupted transfer resumes where the device stopped; a file the device "
            "already holds is not sent again. On a noisy line a lost or garbled answer "
            "makes the upload reconnect and go on from what the device holds, by itself; "
            "the device's copy is checked by its SHA-256 at the end. A mask must have the "
            "image's aspect ratio: it is checked before anything is sent."
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
    """A one-line progress bar on stderr: bar, percent, sizes, rate.

    :meth:`note` prints a line of its own (the bar's line is finished first, and the
    bar is drawn again at the next update); :meth:`close` finishes the bar's line, so
    whatever is printed next starts on a line of its own.
    """

    def __init__(self, label: str, width: int = 30, stream: TextIO | None = None) -> None:
        self.label = label
        self.width = width
        self.stream = stream or sys.stderr
        self.t0 = time.monotonic()
        self.first: int | None = None
        self.open = False

    def __call__(self, done: int, total: int) -> None:
        if self.first is None:
            self.first = done
        frac = done / total if total else 1.0
        fill = int(frac * self.width)
        dt = max(time.monotonic() - self.t0, 1e-6)
        rate = human_size((done - self.first) / dt)
        self.stream.write(
            f"\r{self.label} [{'#' * fill}{'.' * (self.width - fill)}] {frac:6.1%} "
            f"{human_size(done)} of {human_size(total)}, {rate}/s "
        )
        self.open = True
        if done >= total:
            self.close()
        self.stream.flush()

    def note(self, line: str) -> None:
        """Print ``line`` on a line of its own."""
        self.close()
        self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        """Finish the bar's line if it is open."""
        if self.open:
            self.stream.write("\n")
            self.stream.flush()
            self.open = False


def local_item(path: Path, name: str | None) -> tuple[str, bytes]:
    """(device name, bytes) of a local file, checked as the device will check it."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise ImageError(f"cannot read {path}: {e.strerror or e}") from None
    device_name = check_name(name or path.name)
    check_content(path, device_name, Limits())
    return device_name, data


def check_mask_fits(image: bytes, mask: bytes, mask_path: Path) -> None:
    """Refuse a mask that the device would refuse with this image (not its aspect)."""
    from adaproj_edge.content.mask import decode_mask
    from adaproj_edge.fileio import image_size

    size = image_size(image)
    if size is None:
        raise ImageError("cannot read the image's size from its header")
    decode_mask(mask, size, str(mask_path))


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.link import client

    options = link_options(args)
    if args.mask is not None and args.no_mask:
        raise InputError("--mask and --no-mask contradict each other")
    items = [local_item(args.image, args.name)]
    if args.mask is not None:
        items.append(local_item(args.mask, None))
        check_mask_fits(items[0][1], items[1][1], args.mask)

    async def go() -> None:
        async with client.connect(args.port, options["timeout_s"]) as c:
            for name, data in items:
                bar = ProgressBar(name)
                try:
                    start = await client.upload(
                        c, data, name, bar, resume=not args.no_resume, notify=bar.note, **options
                    )
                finally:
                    bar.close()
                size = human_size(len(data))
                if start == len(data):
                    print(f"{name}: already on the device")
                elif start:
                    print(f"{name}: resumed at byte {start}, {size} on the device")
                else:
                    print(f"{name}: {size} on the device")
            if args.activate:
                mask = items[1][0] if len(items) > 1 else None
                active = await client.activate(
                    c, items[0][0], mask, settings_of(args), keep_mask=not args.no_mask, **options
                )
                print(f"showing {describe_active(active)}")

    client.run(go())
    return 0


def describe_active(active: dict[str, Any]) -> str:
    """``photo.jpg with mask m.png (mode content, threshold 0.67)`` for an active record."""
    mask = f" with mask {active['mask']}" if active.get("mask") else " (no mask)"
    settings = active.get("settings") or {}
    how = ", ".join(f"{k} {v}" for k, v in settings.items())
    return f"{active['image']}{mask}" + (f" ({how})" if how else "")
