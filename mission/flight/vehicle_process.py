"""Starting the built-in simulated vehicle as a child process whose life is tied to the parent's.

Why: ``fly-mission`` without ``--connect`` runs ``python -m sitl.vehicle`` beside itself; a ``kill -9`` of
``fly-mission`` must not leave it running.  The child asks the kernel for SIGTERM when its parent dies
(``prctl(PR_SET_PDEATHSIG)``, Linux) and, everywhere, polls its parent pid (``--parent-pid``).
"""

from __future__ import annotations

import ctypes
import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys

PR_SET_PDEATHSIG = 1


def free_udp_port() -> int:
    """A UDP port that is free on 127.0.0.1 now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def die_with_parent() -> None:
    """In a child before exec: have the kernel send SIGTERM when the parent dies (Linux; elsewhere a no-op)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the vehicle's parent-pid poll still ends it
        pass


def spawn_vehicle(
    port: int,
    speedup: float,
    home: tuple[float, float, float],
    kin,
    seed: int,
    verbose: bool = False,
) -> subprocess.Popen:
    """Start the simulated vehicle (``python -m sitl.vehicle``) sending to 127.0.0.1:``port``.

    ``kin`` is the mission's full ``Kinematics`` (cruise speed, acceleration, climb rate, corner exponent,
    yaw rate, ...), passed as JSON so that the flown time matches the pre-flight budget check.
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
        preexec_fn=die_with_parent,
    )


def stop_vehicle(proc: subprocess.Popen | None) -> None:
    """Terminate the vehicle process (kill it if it does not exit within 5 s)."""
    if proc is None:
        return
    proc.terminate()
    try:
        proc.wait(5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)
