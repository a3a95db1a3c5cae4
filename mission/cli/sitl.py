"""Run the simulated MAVLink vehicle alone, for QGroundControl, MAVProxy or ``fly-mission
--connect``.

The vehicle sends MAVLink 2 over UDP to the ground station's port (like PX4 SITL): ``rfsl sitl``
then ``fly-mission missions/spiral.yaml --connect udpin://0.0.0.0:14540``; ``rfsl sitl --port
14550`` for QGroundControl; ``mavproxy.py --master udpin:0.0.0.0:14540``.  See sitl/README.md.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from sitl.cli import add_arguments as vehicle_arguments  # argparse only: no heavy import here

    vehicle_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from mission.cli.main import check_number
    from mission.defaults import MAX_DURATION_S, MAX_SPEEDUP
    from mission.errors import InputError
    from sitl.vehicle import run_from_args

    if args.speedup <= 0:
        raise InputError(f"must be positive, got {args.speedup:g}", field="--speedup")
    check_number(args.speedup, "--speedup", 0.0, MAX_SPEEDUP, strict_lo=True)
    if args.speed_factor is not None and not 0 < args.speed_factor <= 2:
        raise InputError(f"must be in (0, 2], got {args.speed_factor:g}", field="--speed-factor")
    check_number(args.gust, "--gust", 0.0, 30.0)
    if args.duration is not None:
        check_number(args.duration, "--duration", 0.0, MAX_DURATION_S, strict_lo=True)
    if args.cruise_speed is not None:
        check_number(args.cruise_speed, "--cruise-speed", 0.0, 30.0, strict_lo=True)
    if args.seed < 0:
        raise InputError(f"must be >= 0, got {args.seed}", field="--seed")
    if args.url is not None:
        check_vehicle_url(args.url)
    else:
        check_port(args.port)
        from mission.flight.preflight import check_host

        check_host(args.host, args.host, "--host")
    if args.home:
        try:
            from sitl.cli import parse_home

            lat, lon, alt = parse_home(args.home)
        except ValueError as e:
            raise InputError(str(e), field="--home") from None
        from mission.cli.importer import parse_origin

        # the ranges: |lat| <= 90, |lon| <= 180, a plausible altitude
        parse_origin(args.home, "--home")
    if args.kinematics:
        from sitl.cli import parse_kinematics

        try:
            parse_kinematics(args.kinematics)
        except (TypeError, ValueError) as e:
            raise InputError(str(e), field="--kinematics") from None
    try:
        return run_from_args(args)
    except OSError as e:  # the port taken, the host not local
        raise InputError(
            f"cannot open the vehicle's link: {e.strerror or e}",
            field="--url" if args.url else "--port",
        ) from None


def check_port(port: int, field: str = "--port") -> int:
    """A UDP/TCP port number: 1-65535."""
    from mission.errors import InputError

    if not 0 < port < 65536:
        raise InputError(f"must be a port number 1-65535, got {port}", field=field)
    return port


# pymavlink connection strings the vehicle can serve: network only (it has no serial port to open)
VEHICLE_SCHEMES = ("udpin", "udpout", "udp", "udpbcast", "tcp", "tcpin")


def check_vehicle_url(url: str) -> None:
    """``--url`` is a pymavlink network address ``SCHEME:HOST:PORT`` (``tcpin:0.0.0.0:5760``);
    anything else is one line (a garbage URL ended in a traceback about a missing ``serial``
    module)."""
    from mission.errors import InputError
    from mission.flight.preflight import check_host

    scheme, _, rest = url.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme not in VEHICLE_SCHEMES or not host or not port.isdigit():
        raise InputError(
            f"expected SCHEME:HOST:PORT with a scheme among {', '.join(VEHICLE_SCHEMES)} "
            f"(e.g. tcpin:0.0.0.0:5760), got {url!r}",
            field="--url",
        )
    check_port(int(port), "--url")
    check_host(host, url, "--url")
