"""The flight log a ``fly-mission`` run under test writes, found and waited for (the end-to-end
flight tests)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from pathlib import Path


def log_of(out: Path) -> Path:
    """The one ``flight.csv`` under ``out``."""
    logs = sorted(out.glob("*/flight.csv"))
    assert len(logs) == 1, logs
    return logs[0]


def wait_rows(out: Path, rows: int, timeout: float) -> Path:
    """The log under ``out`` once it holds more than ``rows`` rows: a moment picked on the flight's
    own progress, not on the wall clock or on stderr text."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        logs = list(out.glob("*/flight.csv"))
        if logs and sum(1 for _ in open(logs[0])) > rows:
            return logs[0]
        time.sleep(0.5)
    raise AssertionError(f"no log with {rows} rows under {out}")


def _drain(stream, into: list[str]) -> threading.Thread:
    """Read ``stream`` to its end into ``into`` in a thread: a pipe nobody reads fills and blocks
    the flight that writes it."""
    t = threading.Thread(target=lambda: into.extend(stream), daemon=True)
    t.start()
    return t


def signal_group_at_rows(
    p: subprocess.Popen, out: Path, rows: int, sig: int, wait_s: float, exit_s: float
) -> str:
    """Send ``sig`` to the whole process group of ``p`` (as a terminal does) once its log under
    ``out`` holds ``rows`` rows, and give its stderr once it exits; the group is killed if anything
    of it is left. Its output is read all along; a flight that never reaches ``rows`` fails with
    the end of its stderr, so the failure says why."""
    err: list[str] = []
    readers = [_drain(p.stdout, []), _drain(p.stderr, err)]
    try:
        try:
            wait_rows(out, rows, wait_s)
        except AssertionError as e:
            rc = p.poll()
            state = "runs" if rc is None else f"exited {rc}"
            tail = "".join(err)[-2000:]
            raise AssertionError(f"{e}; fly-mission {state}, its stderr ends:\n{tail}") from None
        os.killpg(p.pid, sig)
        p.wait(timeout=exit_s)
        for t in readers:
            t.join(timeout=10)
        return "".join(err)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
