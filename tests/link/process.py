"""``adaproj link`` in a process of its own, serving one side of a pty pair.

The crash, memory and hang-up tests run the real server this way: a host (``smpclient``
through :mod:`adaproj_edge.link.client`, or raw frames) talks to it over the pty, and
the test reads the server's peak resident memory from ``/proc``.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import threading
from pathlib import Path
from typing import IO

from adaproj_edge.hal.serial import PtyPair

LINK_COMMAND = (sys.executable, "-m", "adaproj_edge.cli", "link")


def peak_rss_mb(pid: int) -> float:
    """The process's peak resident memory (``VmHWM``), MiB, from ``/proc``."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise AssertionError(f"no VmHWM for process {pid}")


class LinkProcess:
    """``adaproj link`` serving ``pty``: its master (``--fd``, the default) or, with
    ``port=True``, its slave path opened by pyserial as on ``/dev/ttyGS0``."""

    def __init__(
        self,
        pty: PtyPair,
        store: Path,
        log: IO[str],
        *extra: str,
        port: bool = False,
    ) -> None:
        self.pty, self.store, self.log, self.extra, self.port = pty, store, log, extra, port
        self.proc: subprocess.Popen[str] | None = None
        self.copier: threading.Thread | None = None
        self.lines: list[str] = []

    def start(self) -> None:
        drain(self.pty.master)  # what the host sent to the dead server is gone (USB re-plug)
        where = ("--port", self.pty.path) if self.port else ("--fd", str(self.pty.master))
        self.proc = subprocess.Popen(
            [*LINK_COMMAND, *where, "--store", str(self.store), *self.extra],
            pass_fds=() if self.port else (self.pty.master,),
            stderr=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stderr is not None
        for line in self.proc.stderr:  # wait for "SMP server up"
            self._keep(line)
            if "SMP server up" in line:
                break
        self.copier = threading.Thread(target=self._copy_log, args=(self.proc.stderr,))
        self.copier.start()

    def _keep(self, line: str) -> None:
        self.lines.append(line)
        self.log.write(line)

    def _copy_log(self, stream: IO[str]) -> None:
        for line in stream:
            self._keep(line)

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def peak_rss_mb(self) -> float:
        return peak_rss_mb(self.pid)

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()

    def wait_dead(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait(10)
            if self.copier is not None:
                self.copier.join(10)
            assert self.proc.stderr is not None
            self.proc.stderr.close()
            self.proc = None


def drain(fd: int) -> None:
    """Read and drop whatever is waiting on ``fd``."""
    while select.select([fd], [], [], 0)[0]:
        try:
            if not os.read(fd, 65536):
                return
        except OSError:
            return
