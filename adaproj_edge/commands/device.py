"""``adaproj device``: list, inspect, switch and delete content on the projector."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from adaproj_edge.commands.push import add_port, add_settings, settings_of
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
    a = acts.add_parser("activate", help="show an item (with a mask and settings)")
    a.add_argument("name", help="item on the device")
    a.add_argument("--mask", help="mask item on the device")
    add_port(a)
    add_settings(a)
    a = acts.add_parser("delete", help="remove an item")
    a.add_argument("name", help="item on the device")
    add_port(a)
    a = acts.add_parser("screenshot", help="save the frame shown now as PNG")
    a.add_argument("out", type=Path, help="where to write the PNG")
    add_port(a)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.link import client

    async def go() -> None:
        async with client.connect(args.port) as c:
            if args.action == "list":
                r = await client.call(c, client.ListRead())
                for i in r.items:
                    mark = "*" if r.active and i["name"] == r.active.get("image") else " "
                    dur = i.get("dur")
                    length = f"  {dur:.1f} s" if isinstance(dur, (int, float)) else ""
                    print(f"{mark} {i['name']:40s} {i['len']:>10d} B  {i['w']}x{i['h']}{length}")
                for q in r.pending:
                    print(f"  {q['name']:40s} {q['off']:>10d}/{q['len']} B received (pending)")
                print(f"used {r.used} of {r.quota} bytes")
            elif args.action == "status":
                r = await client.call(c, client.StatusRead())
                doc = {"device": r.device, "store": r.store, "link": r.link}
                print(json.dumps(doc, indent=2, default=str))
            elif args.action == "activate":
                req = client.ActivateWrite(
                    image=args.name, mask=args.mask, settings=settings_of(args)
                )
                r = await client.call(c, req)
                print(f"showing {json.dumps(r.active)}")
            elif args.action == "delete":
                await client.call(c, client.DeleteWrite(name=args.name))
                print(f"deleted {args.name}")
            else:
                png = await client.download_screenshot(c)
                atomic_write_bytes(args.out, png)
                print(f"wrote {args.out} ({len(png)} bytes)")

    client.run(go())
    return 0
