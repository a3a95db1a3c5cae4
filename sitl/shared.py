"""A real autopilot's SITL from ``../shared/sitl`` (ArduCopter or PX4): started from its
``start.sh`` (which prints its PID), its log, whether it is alive, a bounded stop.

Why here: the end-to-end tests and ``benchmarks/bench_sitl_seeds.py`` start and stop the same
SITLs; one home keeps the start-up wait and the stop alike.  Errors are ``SitlStartError`` (with the
log's tail), so a test can fail or skip and a benchmark can report, each its own way.
"""

from __future__ import annotations

import os
import random
import signal
import socket
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

START_TIMEOUT_S = 60.0  # a SITL not ready by then has failed to start


class SitlStartError(RuntimeError):
    """A SITL that did not start (the message ends with its log's tail)."""


def free_instance(
    lo: int, hi: int, ports: Callable[[int], tuple[int, ...]], udp: bool
) -> int | None:
    """A random instance in lo..hi whose ``ports(instance)`` (UDP or TCP) are all free now; None
    when none was found in 50 tries."""
    kind = socket.SOCK_DGRAM if udp else socket.SOCK_STREAM
    for _ in range(50):
        i = random.randint(lo, hi)
        try:
            for port in ports(i):
                with socket.socket(socket.AF_INET, kind) as s:
                    s.bind(("0.0.0.0" if udp else "127.0.0.1", port))
            return i
        except OSError:
            continue
    return None


class SharedSitl:
    """One SITL process writing its log ``log_name`` in its run folder ``run``."""

    log_name = "sitl.log"

    def __init__(self, run: Path, log_name: str | None = None):
        self.run, self.pid = Path(run), None
        if log_name is not None:
            self.log_name = log_name

    def launch(self, script: Path, args: list[str], ready: str, what: str) -> int:
        """Run ``script`` (a ``start.sh``) with ``RUN`` = ``self.run`` and wait until its log says
        ``ready`` ("" : no wait); returns the SITL's PID."""
        self.run.mkdir(parents=True, exist_ok=True)
        out = subprocess.run(
            [str(script), *args],
            env=dict(os.environ, RUN=str(self.run)),
            capture_output=True,
            text=True,
            timeout=30,
        )
        try:
            self.pid = int(out.stdout.split()[-1])
        except (IndexError, ValueError):
            raise SitlStartError(f"{what}: {script} printed no PID: {out.stderr[-2000:]}") from None
        end = time.monotonic() + START_TIMEOUT_S
        while ready not in self.log():
            if time.monotonic() > end or not self.alive():
                raise SitlStartError(f"{what} did not start: " + self.log()[-2000:])
            time.sleep(0.2)
        return self.pid

    def log(self) -> str:
        f = self.run / self.log_name
        return f.read_text(errors="replace") if f.exists() else ""

    def alive(self) -> bool:
        if self.pid is None:
            return False
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        return True

    def stop(self) -> None:
        """SIGTERM, then SIGKILL, each given 5 s."""
        for sig in (signal.SIGTERM, signal.SIGKILL):
            if not self.alive():
                return
            os.kill(self.pid, sig)
            for _ in range(20):
                if not self.alive():
                    return
                time.sleep(0.25)
