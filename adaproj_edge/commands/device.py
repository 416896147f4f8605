"""``adaproj device``: list, inspect, switch and delete content on the projector."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from adaproj_edge.commands._outputs import check_output_file
from adaproj_edge.commands.push import (
    ProgressBar,
    add_port,
    add_settings,
    describe_active,
    human_size,
    link_options,
    settings_of,
)
from adaproj_edge.errors import InputError
from adaproj_edge.fileio import atomic_write_bytes


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "device",
        help="manage the content on the projector over USB serial",
        description="Talk to the projector's SMP server (adaproj group) over USB serial.",
    )
    acts = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    a = acts.add_parser("list", help="items, pending uploads, what is shown, space used")
    add_port(a)
    a = acts.add_parser("status", help="the device's state, coverage, last warp, errors")
    add_port(a)
    a = acts.add_parser(
        "activate",
        help="show an item (with a mask and settings)",
        description=(
            "Show item NAME. Without --mask, an item that is already shown keeps its "
            "mask (--no-mask drops it); another item is shown without a mask. Settings "
            "not given take the device's defaults."
        ),
    )
    a.add_argument("name", help="item on the device")
    a.add_argument("--mask", help="mask item on the device")
    add_port(a)
    add_settings(a)
    a = acts.add_parser("delete", help="remove an item")
    a.add_argument("name", help="item on the device")
    add_port(a)
    a = acts.add_parser("screenshot", help="save the frame shown now as PNG")
    a.add_argument("out", type=Path, nargs="?", help="where to write the PNG")
    a.add_argument("--out", type=Path, dest="out_option", metavar="OUT", help="the same")
    add_port(a)
    p.set_defaults(run=run)


def item_lines(listed: Any) -> list[str]:
    """The lines of ``adaproj device list`` for a list response."""
    active = listed.active or {}
    lines = []
    for i in listed.items:
        mark = (
            "*"
            if i["name"] == active.get("image")
            else "m"
            if i["name"] == active.get("mask")
            else " "
        )
        dur = i.get("dur")
        length = f"  {dur:.1f} s" if isinstance(dur, (int, float)) else ""
        size = human_size(i["len"])
        lines.append(f"{mark} {i['name']:40s} {size:>10s}  {i['w']}x{i['h']}{length}")
    for q in listed.pending:
        got = f"{human_size(q['off'])} of {human_size(q['len'])}"
        lines.append(f"  {q['name']:40s} {got} received (pending: push it again to finish)")
    lines.append(f"used {human_size(listed.used)} of {human_size(listed.quota)}")
    if active:
        lines.append(f"showing {describe_active(active)}  (* image, m mask)")
    return lines


def screenshot_path(args: argparse.Namespace) -> Path:
    """Where ``device screenshot`` writes: the path given as an argument or with --out."""
    given = [p for p in (args.out, args.out_option) if p is not None]
    if len(given) != 1:
        raise InputError(
            "screenshot: give one PNG file to write, e.g. `adaproj device screenshot shot.png`"
        )
    return check_output_file(given[0], "screenshot", (".png",))


def run(args: argparse.Namespace) -> int:
    if args.action == "screenshot":
        args.out = screenshot_path(args)
    from adaproj_edge.link import client
    from adaproj_edge.link.host_requests import ListRead, StatusRead

    options = link_options(args)
    if getattr(args, "mask", None) is not None and args.no_mask:
        raise InputError("--mask and --no-mask contradict each other")
    notes = ProgressBar(args.action)

    async def go() -> None:
        async with client.connect(args.port, options["timeout_s"]) as c:
            kw = {**options, "notify": notes.note}
            if args.action == "list":
                print("\n".join(item_lines(await client.call(c, ListRead(), **kw))))
            elif args.action == "status":
                r = await client.call(c, StatusRead(), **kw)
                doc = {"device": r.device, "store": r.store, "link": r.link}
                print(json.dumps(doc, indent=2, default=str))
            elif args.action == "activate":
                active = await client.activate(
                    c, args.name, args.mask, settings_of(args), keep_mask=not args.no_mask, **kw
                )
                print(f"showing {describe_active(active)}")
            elif args.action == "delete":
                await client.delete(c, args.name, **kw)
                print(f"deleted {args.name}")
            else:
                png = await client.download_screenshot(c, **kw)
                atomic_write_bytes(args.out, png)
                print(f"wrote {args.out} ({human_size(len(png))})")

    client.run(go())
    return 0
