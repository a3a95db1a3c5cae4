"""Command line of the simulated vehicle (``python -m sitl.vehicle``, ``rfsl sitl``): its options
and their parsing.

Light at import (argparse only): ``rfsl``'s parser imports ``add_arguments`` without loading numpy
or pymavlink.  Building and running the vehicle from these options (``run_from_args``) lives in
``sitl.vehicle``, so that this module never imports the vehicle back.
"""

from __future__ import annotations

import argparse
import dataclasses
import json


def parse_home(text: str) -> tuple[float, float, float]:
    """``LAT,LON[,ALT]`` -> a tuple (the altitude is the ground AMSL, default 0)."""
    parts = [float(p) for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise ValueError(f"--home wants LAT,LON[,ALT], got {text!r}")
    return (parts[0], parts[1], parts[2] if len(parts) == 3 else 0.0)


def parse_kinematics(text: str | None):
    """``--kinematics`` JSON (an object of ``Kinematics`` fields) -> ``Kinematics``; None ->
    defaults."""
    from mission.trajectory.kinematics import Kinematics

    if not text:
        return Kinematics()
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"--kinematics is not valid JSON: {e}") from None
    names = {f.name for f in dataclasses.fields(Kinematics)}
    if not isinstance(d, dict) or set(d) - names:
        raise ValueError(
            f"--kinematics wants a JSON object with keys among {sorted(names)}, got {text!r}"
        )
    return Kinematics(**{k: None if v is None else float(v) for k, v in d.items()})


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m sitl.vehicle", description="A simulated PX4-like MAVLink multicopter."
    )
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``python -m sitl.vehicle`` and ``rfsl sitl``."""
    p.add_argument(
        "--port",
        type=int,
        default=14540,
        help="ground-station UDP port the vehicle sends to (PX4 SITL: 14540; QGroundControl: "
        "14550)",
    )
    p.add_argument("--host", default="127.0.0.1", help="ground-station host (default 127.0.0.1)")
    p.add_argument(
        "--url",
        default=None,
        help="full pymavlink URL instead of --host/--port (e.g. tcpin:0.0.0.0:5760)",
    )
    p.add_argument(
        "--speedup", type=float, default=1.0, help="simulated seconds per wall-clock second"
    )
    p.add_argument(
        "--home", default=None, help="LAT,LON[,ALT] of the take-off point (default: AFAR field)"
    )
    p.add_argument(
        "--kinematics",
        default=None,
        help="JSON object of Kinematics fields (cruise_speed_mps, accel_mps2, climb_rate_mps, "
        "corner_exponent, yaw_rate_dps, ...); fly-mission passes the mission's full kinematics "
        "here",
    )
    p.add_argument(
        "--cruise-speed",
        type=float,
        default=None,
        help="default cruise speed, m/s (overrides the one in --kinematics; default 5)",
    )
    p.add_argument(
        "--profile",
        choices=("default", "px4"),
        default="default",
        help="default: flies the project's kinematics exactly; px4: like PX4 v1.16 SITL (legs "
        "at 93 %% of the "
        "speed asked, return at its MPC_XY_CRUISE parameter, 4.8 m/s unless set; climb 1.5 "
        "m/s, landing "
        "1.5 m/s then 0.7 m/s below 5 m; STATUSTEXT only while a ground-station heartbeat "
        "arrived within 2.5 "
        "simulated s)",
    )
    p.add_argument(
        "--speed-factor",
        type=float,
        default=None,
        help="fly legs at this fraction of the speed asked (default: the profile's, 1 or 0.93)",
    )
    p.add_argument(
        "--statustext-log",
        default=None,
        help="append every STATUSTEXT generated (sent or dropped) to this file as JSON lines",
    )
    p.add_argument("--gust", type=float, default=1.5, help="wind gust standard deviation, m/s")
    p.add_argument("--seed", type=int, default=0, help="seed of the wind and turbulence")
    p.add_argument(
        "--duration", type=float, default=None, help="stop after this many wall-clock seconds"
    )
    p.add_argument(
        "--parent-pid", type=int, default=None, help="exit when this parent process is gone"
    )
    p.add_argument("-v", "--verbose", action="store_true", help="print state changes to stderr")
