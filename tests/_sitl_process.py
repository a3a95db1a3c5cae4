"""A real autopilot SITL from ../shared (``start.sh`` prints its PID) as a test sees it: its log,
whether it is alive, a bounded stop.  Shared by the ArduPilot and PX4 end-to-end tests."""

from __future__ import annotations

import os
import random
import signal
import socket
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import pytest


def free_instance(
    lo: int, hi: int, ports: Callable[[int], tuple[int, ...]], udp: bool, what: str
) -> int:
    """A random instance in lo..hi whose ``ports(instance)`` (UDP or TCP) are all free now; skip
    when none is."""
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
    pytest.skip(f"no free {what} instance ports")


class SitlProcess:
    """One SITL process in its own run folder ``run``; ``log_name`` is its log there."""

    log_name = "sitl.log"

    def __init__(self, root: Path):
        self.root, self.pid, self.url, self.run = root, None, "", root

    def launch(self, script: Path, args: list[str], ready: str, what: str) -> None:
        """Run ``script`` (a start.sh) with ``RUN`` = ``self.run`` and wait until its log says
        ``ready``."""
        out = subprocess.run(
            [str(script), *args],
            env=dict(os.environ, RUN=str(self.run)),
            capture_output=True,
            text=True,
            timeout=30,
        )
        self.pid = int(out.stdout.split()[-1])
        end = time.monotonic() + 60
        while ready not in self.log():
            if time.monotonic() > end or not self.alive():
                pytest.fail(f"{what} did not start: " + self.log()[-2000:])
            time.sleep(0.2)

    def log(self) -> str:
        f = self.run / self.log_name
        return f.read_text(errors="replace") if f.exists() else ""

    def alive(self) -> bool:
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        return True

    def stop(self) -> None:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            if self.pid is None or not self.alive():
                return
            os.kill(self.pid, sig)
            for _ in range(20):
                if not self.alive():
                    return
                time.sleep(0.25)
