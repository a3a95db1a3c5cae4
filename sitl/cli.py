"""Command line of the simulated vehicle (``python -m sitl.vehicle``, ``rfsl sitl``): options and start-up.

Light at import (argparse only): ``rfsl``'s parser imports ``add_arguments`` without loading numpy or
pymavlink; the vehicle itself is imported when it runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys


def parse_home(text: str) -> tuple[float, float, float]:
    """``LAT,LON[,ALT]`` -> a tuple (the altitude is the ground AMSL, default 0)."""
    parts = [float(p) for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise ValueError(f"--home wants LAT,LON[,ALT], got {text!r}")
    return (parts[0], parts[1], parts[2] if len(parts) == 3 else 0.0)


def parse_kinematics(text: str | None):
    """``--kinematics`` JSON (an object of ``Kinematics`` fields) -> ``Kinematics``; None -> defaults."""
    from mission.trajectory.kinematics import Kinematics

    if not text:
        return Kinematics()
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"--kinematics is not valid JSON: {e}") from None
    names = {f.name for f in dataclasses.fields(Kinematics)}
    if not isinstance(d, dict) or set(d) - names:
        raise ValueError(f"--kinematics wants a JSON object with keys among {sorted(names)}, got {text!r}")
    return Kinematics(**{k: None if v is None else float(v) for k, v in d.items()})


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m sitl.vehicle", description="A simulated PX4-like MAVLink multicopter.")
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``python -m sitl.vehicle`` and ``rfsl sitl``."""
    p.add_argument(
        "--port",
        type=int,
        default=14540,
        help="ground-station UDP port the vehicle sends to (PX4 SITL: 14540; QGroundControl: 14550)",
    )
    p.add_argument("--host", default="127.0.0.1", help="ground-station host (default 127.0.0.1)")
    p.add_argument(
        "--url", default=None, help="full pymavlink URL instead of --host/--port (e.g. tcpin:0.0.0.0:5760)"
    )
    p.add_argument("--speedup", type=float, default=1.0, help="simulated seconds per wall-clock second")
    p.add_argument("--home", default=None, help="LAT,LON[,ALT] of the take-off point (default: AFAR field)")
    p.add_argument(
        "--kinematics",
        default=None,
        help="JSON object of Kinematics fields (cruise_speed_mps, accel_mps2, climb_rate_mps, "
        "corner_exponent, yaw_rate_dps, ...); fly-mission passes the mission's full kinematics here",
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
        help="default: flies the project's kinematics exactly; px4: like PX4 v1.16 SITL (legs at 93 %% of the "
        "speed asked, return at its MPC_XY_CRUISE parameter, 4.8 m/s unless set; climb 1.5 m/s, landing "
        "1.5 m/s then 0.7 m/s below 5 m; STATUSTEXT only while a ground-station heartbeat arrived within 2.5 "
        "simulated s)",
    )
    p.add_argument("--speed-factor", type=float, default=None, help="fly legs at this fraction of the speed asked "
                   "(default: the profile's, 1 or 0.93)")
    p.add_argument("--statustext-log", default=None, help="append every STATUSTEXT generated (sent or dropped) "
                   "to this file as JSON lines")
    p.add_argument("--gust", type=float, default=1.5, help="wind gust standard deviation, m/s")
    p.add_argument("--seed", type=int, default=0, help="seed of the wind and turbulence")
    p.add_argument("--duration", type=float, default=None, help="stop after this many wall-clock seconds")
    p.add_argument("--parent-pid", type=int, default=None, help="exit when this parent process is gone")
    p.add_argument("-v", "--verbose", action="store_true", help="print state changes to stderr")


def run_from_args(args: argparse.Namespace) -> int:
    """Build the vehicle from parsed options and run it until killed."""
    if args.speedup <= 0:
        raise ValueError("--speedup must be positive")
    from sitl.protocol import DEFAULT_HOME
    from sitl.vehicle import SimVehicle

    home = parse_home(args.home) if args.home else DEFAULT_HOME
    url = args.url or f"udpout:{args.host}:{args.port}"
    kin = parse_kinematics(args.kinematics)
    if args.cruise_speed is not None:
        kin = dataclasses.replace(kin, cruise_speed_mps=float(args.cruise_speed))
    from sitl.protocol import PROFILES

    profile = PROFILES[args.profile]
    if args.speed_factor is not None:
        if not 0 < args.speed_factor <= 2:
            raise ValueError("--speed-factor must be in (0, 2]")
        profile = dataclasses.replace(profile, speed_factor=float(args.speed_factor))
    v = SimVehicle(url, home, args.speedup, args.seed, kin, gust_mps=args.gust, verbose=args.verbose,
                   profile=profile, statustext_log=args.statustext_log)
    print(
        f"sitl: simulated PX4 quadrotor ({profile.name} profile), MAVLink 2 on {url}, "
        f"home {home[0]:.6f},{home[1]:.6f}, speed-up {args.speedup:g}",
        file=sys.stderr,
        flush=True,
    )
    try:
        v.run(args.duration, args.parent_pid)
    except KeyboardInterrupt:
        pass
    return 0


def main(argv: list[str] | None = None) -> int:
    return run_from_args(build_parser().parse_args(argv))
