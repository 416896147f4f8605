"""A session's serial traffic through the device's own SMP server, in a replay.

Each recorded ``rx`` chunk is decoded and answered at its recorded time, on the
replay's thread, with the runtime as the server's content sink and a content store of
its own, so a content push recorded mid-session switches the content at the same
point. What the server answers is compared, reply by reply, with the recorded ``tx``;
a difference is counted (``tx_mismatches``), not an error. Bad bytes are logged and
dropped, as on the device.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from adaproj_edge.app.report import rel_s
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.link.framing import FrameDecoder
from adaproj_edge.link.message import parse_header
from adaproj_edge.link.server import Server
from adaproj_edge.link.store import ContentStore
from adaproj_edge.session.records import SerialTraffic

log = logging.getLogger(__name__)

LISTED_MISMATCHES = 10


class LinkReplay:
    """The device's SMP server on the recorded serial bytes, driven from the replay loop.

    The server (and its store) is made at the first ``rx`` chunk, so a session
    without serial traffic leaves no store behind.
    """

    def __init__(self, store_root: Path, runtime: Runtime) -> None:
        self.store_root = store_root
        self.rt = runtime
        self.server: Server | None = None
        self.decoder: FrameDecoder | None = None
        self.recorded = FrameDecoder(0xFFFF - 2)
        self.replies: list[tuple[int, bytes]] = []
        self.recorded_replies: list[bytes] = []
        self.rx_bytes = 0
        self.tx_bytes = 0

    def _open(self) -> tuple[Server, FrameDecoder]:
        if self.server is None or self.decoder is None:
            self.server = Server(ContentStore(self.store_root), self.rt)
            self.server.on_reset = self.server.restore_active
            self.decoder = FrameDecoder(self.server.max_message)
        return self.server, self.decoder

    def feed(self, rec: SerialTraffic) -> None:
        """Feed one recorded chunk (rx: to the server; tx: the recorded answers)."""
        if rec.direction == "tx":
            self.tx_bytes += len(rec.data)
            self.recorded_replies.extend(self.recorded.feed(rec.data))
            return
        if rec.direction != "rx":
            log.warning("ignored serial bytes with direction %r", rec.direction)
            return
        self.rx_bytes += len(rec.data)
        server, decoder = self._open()
        for message in decoder.feed(rec.data):
            reply = server.handle(message)
            if reply is not None:
                self.replies.append((rec.receive_ns, reply))
            if server.after_reply is not None:
                server.after_reply()

    def summary(self, t0: int) -> dict[str, Any]:
        """The ``link`` section of the replay summary (``t0``: the session start, ns)."""
        got = self.replies
        want = self.recorded_replies
        mismatches: list[dict[str, Any]] = []
        n_bad = abs(len(got) - len(want))
        for i, ((t_ns, reply), recorded) in enumerate(zip(got, want, strict=False)):
            if reply == recorded:
                continue
            n_bad += 1
            if len(mismatches) < LISTED_MISMATCHES:
                _, _, _, _, group, seq, cmd = parse_header(reply)
                mismatches.append(
                    {"reply": i, "t_s": rel_s(t_ns, t0), "group": group, "command": cmd, "seq": seq}
                )
        counters = dict(self.server.counters) if self.server is not None else {}
        dropped = dict(self.decoder.stats.dropped) if self.decoder is not None else {}
        return {
            "rx_bytes": self.rx_bytes,
            "tx_bytes": self.tx_bytes,
            "requests": counters.get("requests", 0),
            "refused": counters.get("errors", 0),
            "ignored": counters.get("ignored", 0),
            "dropped_frames": dropped,
            "content_activations": sum(
                1
                for e in self.rt.telemetry.events
                if e["event"] == "content" and e.get("source") == "link"
            ),
            "replies": len(got),
            "recorded_replies": len(want),
            "tx_mismatches": n_bad,
            "mismatched": mismatches,
        }
