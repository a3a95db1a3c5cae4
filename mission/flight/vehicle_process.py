"""Starting the built-in simulated vehicle as a child process whose life is tied to the parent's.

Why: ``fly-mission`` without ``--connect`` runs ``python -m sitl.vehicle`` beside itself; a ``kill
-9`` of ``fly-mission`` must not leave it running.  The child asks the kernel for SIGKILL when its
parent dies (``prctl(PR_SET_PDEATHSIG)``, Linux) and, everywhere, polls its parent pid
(``--parent-pid``).  Children (the vehicle, the live-estimate worker) ignore the terminal's SIGINT,
SIGTERM and SIGHUP (``ignore_terminal_signals``): a Ctrl-C or a lost SSH session reaches the whole
process group, and the parent, not the signal, decides when they stop (after the landing), so it
stops them itself (SIGKILL).
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys

PR_SET_PDEATHSIG = 1
TERMINAL_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def free_udp_port() -> int:
    """A UDP port that is free on 127.0.0.1 now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def die_with_parent() -> None:
    """In a child: have the kernel send SIGKILL when the parent dies (Linux; elsewhere a no-op).
    SIGKILL, because the child ignores the terminal's SIGTERM."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the vehicle's parent-pid poll still ends it
        pass


def ignore_terminal_signals() -> None:
    """In a child: ignore SIGINT, SIGTERM and SIGHUP (inherited through exec, and a Python started
    with SIGINT ignored installs no KeyboardInterrupt), so only its parent stops it."""
    for sig in TERMINAL_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


@contextlib.contextmanager
def terminal_signals_ignored():
    """Ignore SIGINT/SIGTERM/SIGHUP in this (main) thread while a child starts, then put the
    handlers back."""
    old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in TERMINAL_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _vehicle_preexec() -> None:
    ignore_terminal_signals()
    die_with_parent()


def spawn_vehicle(
    port: int,
    speedup: float,
    home: tuple[float, float, float],
    kin,
    seed: int,
    verbose: bool = False,
) -> subprocess.Popen:
    """Start the simulated vehicle (``python -m sitl.vehicle``) sending to 127.0.0.1:``port``.

    ``kin`` is the mission's full ``Kinematics`` (cruise speed, acceleration, climb rate, corner
    exponent, yaw rate, ...), passed as JSON so that the flown time matches the pre-flight budget
    check.
    """
    cmd = [
        sys.executable,
        "-m",
        "sitl.vehicle",
        "--port",
        str(port),
        "--speedup",
        f"{speedup:g}",
        "--home",
        f"{home[0]:.9f},{home[1]:.9f},{home[2]:.3f}",
        "--kinematics",
        json.dumps(dataclasses.asdict(kin)),
        "--seed",
        str(seed),
        "--parent-pid",
        str(os.getpid()),
    ] + (["-v"] if verbose else [])
    return subprocess.Popen(
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=None if verbose else subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=_vehicle_preexec,
    )


def stop_vehicle(proc: subprocess.Popen | None) -> None:
    """Stop the vehicle process (SIGKILL: it ignores the terminal's signals; it holds no files)."""
    if proc is None:
        return
    proc.kill()
    proc.wait(5)
