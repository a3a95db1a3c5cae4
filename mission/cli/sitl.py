"""Run the simulated MAVLink vehicle alone, for QGroundControl, MAVProxy or ``fly-mission --connect``.

The vehicle sends MAVLink 2 over UDP to the ground station's port (like PX4 SITL): ``rfsl sitl`` then
``fly-mission missions/spiral.yaml --connect udpin://0.0.0.0:14540``; ``rfsl sitl --port 14550`` for
QGroundControl; ``mavproxy.py --master udpin:0.0.0.0:14540``.  See sitl/README.md.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from sitl.cli import add_arguments as vehicle_arguments  # argparse only: no heavy import here

    vehicle_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from mission.errors import InputError
    from sitl.vehicle import run_from_args

    if args.speedup <= 0:
        raise InputError(f"must be positive, got {args.speedup:g}", field="--speedup")
    if args.speed_factor is not None and not 0 < args.speed_factor <= 2:
        raise InputError(f"must be in (0, 2], got {args.speed_factor:g}", field="--speed-factor")
    if args.home:
        try:
            from sitl.cli import parse_home

            parse_home(args.home)
        except ValueError as e:
            raise InputError(str(e), field="--home") from None
    if args.kinematics:
        from sitl.cli import parse_kinematics

        try:
            parse_kinematics(args.kinematics)
        except (TypeError, ValueError) as e:
            raise InputError(str(e), field="--kinematics") from None
    return run_from_args(args)
