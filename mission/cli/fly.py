"""Fly a mission on a MAVLink autopilot (or the built-in simulated vehicle), log RSS with attitude,
localize.

``fly-mission MISSION.yaml [--connect URL] [--speedup N] [--out DIR] [--no-localize] [--adaptive]``.
Every flight shows and records a live estimate (``mission.flight.estimates``); ``--adaptive`` (or
the mission's ``adaptive: {enabled: true}``) flies the survey part, then rounds planned from it.
Without ``--connect`` (and no ``vehicle.connection`` in the mission file) the simulated vehicle of
``sitl/`` is started on a free local UDP port (it dies with ``fly-mission``).  Options are checked
before anything starts.  Exit codes: 0 flown and landed, 2 bad input (e.g. the mission leaves the
fence, a bad ``--connect``/``--rss-source``/``--out``: nothing is started or uploaded), 3 link lost
/ no autopilot within ``--link-timeout``, 4 the log is incomplete (a write failed: disk full; the
sidecar says how many rows it holds), 130 aborted by Ctrl-C, SIGTERM or SIGHUP (after the return to
launch once airborne).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mission", type=Path, help="mission YAML file (missions/spiral.yaml)")
    parser.add_argument(
        "--connect",
        default=None,
        help="MAVSDK connection URL: udpin://0.0.0.0:14540 (PX4 SITL), tcpout://127.0.0.1:5760 "
        "(ArduPilot SITL), serial:///dev/ttyACM0:57600; default: the built-in vehicle",
    )
    parser.add_argument(
        "--speedup",
        type=float,
        default=None,
        help="speed-up of the built-in simulated vehicle (default: the mission's vehicle.speedup; "
        "missions/spiral.yaml: 1, real time, about 9 min; 20 flies it in about 30 s)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("flights"),
        help="folder for flight logs; each flight gets a new timestamped subfolder",
    )
    parser.add_argument(
        "--no-localize", action="store_true", help="do not run the localizer after landing"
    )
    parser.add_argument(
        "--rss-source",
        default="sim",
        help="sim | aerpaw-fifo:PATH[,QUALITY_PATH] (float32 LE dB, e.g. /root/Power; the "
        "sounder's quality pipe too: logged as rss_quality_db) | udp:[HOST:]PORT",
    )
    parser.add_argument(
        "--link-timeout",
        type=float,
        default=30.0,
        help="wall-clock seconds without telemetry before the flight is given up, and to wait "
        "for an "
        "autopilot to answer at all (default 30)",
    )
    parser.add_argument(
        "--land-timeout",
        type=float,
        default=600.0,
        help="wall-clock seconds to wait for landing after return to launch (default 600)",
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=None,
        help="position/attitude rate requested, Hz of vehicle time (>= 30; default 50, lowered "
        "towards 30 "
        "at high --speedup so that MAVSDK's callbacks keep up)",
    )
    parser.add_argument(
        "--adaptive",
        action="store_true",
        help="after the survey part, fly rounds planned from the live estimate (the mission's "
        "adaptive: block, "
        "defaults otherwise; docs/adaptive.md)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help="seed of the simulated transmitter and RSS noise (default: the mission's "
        "source.seed); seed N "
        "puts the transmitter where `rfsl simulate --seed N` does",
    )
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show the simulated vehicle's messages"
    )


def choose_adaptive(spec, flag: bool):
    """(the ``AdaptiveSpec`` to fly or None, a line to show or None): the mission's ``adaptive:``
    block when enabled or ``--adaptive`` is given (the defaults without a block); a block that is
    present but not enabled (``adaptive: {}``, ``adaptive: null``, ``enabled: false``) says in one
    line that the fixed mission is flown."""
    from mission.adaptive.config import AdaptiveSpec

    a = spec.adaptive if spec.adaptive is not None else AdaptiveSpec()
    if flag or a.enabled:
        return a, None
    if spec.adaptive is not None:
        return None, "adaptive: not enabled (enabled: true or --adaptive): flying the fixed mission"
    return None, None


def _run(args: argparse.Namespace) -> int:
    import os

    from mission.adaptive.feasibility import assert_adaptive
    from mission.cli.main import check_number
    from mission.defaults import MAX_DURATION_S, MAX_RATE_HZ, MAX_SPEEDUP
    from mission.errors import InputError
    from mission.flight.context import FlightError
    from mission.flight.preflight import check_connect, check_out
    from mission.flight.runner import FlyOptions, fly
    from mission.spec import load_mission

    if args.speedup is not None and args.speedup <= 0:
        raise InputError(f"must be positive, got {args.speedup:g}", field="--speedup")
    if args.speedup is not None:
        check_number(args.speedup, "--speedup", 0.0, MAX_SPEEDUP, strict_lo=True)
    if args.rate is not None and args.rate < 30:
        raise InputError(
            f"position/attitude rate must be >= 30 Hz, got {args.rate:g}", field="--rate"
        )
    if args.rate is not None:
        check_number(args.rate, "--rate", 30.0, MAX_RATE_HZ)
    for flag, v in (("--link-timeout", args.link_timeout), ("--land-timeout", args.land_timeout)):
        check_number(v, flag, 0.0, MAX_DURATION_S, strict_lo=True)
    if args.connect is not None:
        check_connect(args.connect, "--connect")  # '' is a mistake, not the built-in vehicle
    check_out(args.out)  # an unwritable --out: refused before the mission file is even read
    if args.seed is not None and args.seed < 0:
        raise InputError(f"must be >= 0, got {args.seed}", field="--seed")
    spec = load_mission(args.mission)
    if args.seed is not None:
        import dataclasses

        spec = dataclasses.replace(spec, source=dataclasses.replace(spec.source, seed=args.seed))
    if args.connect is None and spec.vehicle.connection is not None:
        check_connect(spec.vehicle.connection, "vehicle.connection", source=spec.source_name)
    adaptive, note = choose_adaptive(spec, args.adaptive)
    if note:
        print(note, file=sys.stderr)
    extension = None
    if adaptive is not None:
        from mission.adaptive.rounds import AdaptiveRounds

        assert_adaptive(spec, adaptive)  # before anything starts: one line, exit 2
        extension = AdaptiveRounds(spec, adaptive)
    opts = FlyOptions(
        connect=args.connect,
        speedup=args.speedup,
        out=args.out,
        localize=not args.no_localize,
        rss_source=args.rss_source,
        link_timeout_s=args.link_timeout,
        land_timeout_s=args.land_timeout,
        rate_hz=args.rate,
        verbose=args.verbose,
    )
    if os.name == "nt":  # pragma: no cover - signal handlers need a Unix loop
        raise FlightError("fly-mission needs a Unix-like OS (signal handling)")
    try:
        return fly(spec, opts, extension)
    # bad input (2) and a dead link (3) stay one line; an abort is wrapped at 80 columns
    except FlightError as e:
        from mission.flight.progress import fit_width

        print(f"error: {e}" if e.code in (2, 3) else fit_width(f"error: {e}"), file=sys.stderr)
        return e.code


def run(args: argparse.Namespace) -> int:
    """The command; a Ctrl-C at any moment ends it with 130 (``run_guarded``), never by a second
    signal."""
    from mission.flight.vehicle_process import ignore_terminal_signals

    try:
        return _run(args)
    except KeyboardInterrupt:
        ignore_terminal_signals()
        raise


def main(argv: Sequence[str] | None = None) -> int:
    """Console script ``fly-mission``."""
    from mission.cli.main import standalone_main

    return standalone_main("fly-mission", sys.modules[__name__], argv)


if __name__ == "__main__":
    sys.exit(main())
