"""Benchmark of the flight logging path: RSS rows per second the runner sustains, CPU per
flight-minute.

Flies ``missions/spiral.yaml`` with ``fly-mission`` against the simulated vehicle at high speed-ups
and reports, per speed-up: rows logged per wall-clock second, coverage of the expected samples, and
the CPU seconds (user + system) of the runner and of the vehicle per minute of flown (vehicle) time.
The CPU of each process is read from ``resource.getrusage(RUSAGE_CHILDREN)`` after it exits.

    python benchmarks/bench_logging.py [--speedups 20 50 100] [--mission missions/spiral.yaml]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mission.flight.runner import free_udp_port
from mission.flightlog import read_flight_log
from mission.spec import load_mission

ROOT = Path(__file__).resolve().parents[1]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_one(mission: Path, speedup: float) -> dict:
    """One flight; returns rows, wall seconds, coverage and CPU per flight-minute (runner incl.
    vehicle)."""
    kin = json.dumps(dataclasses.asdict(load_mission(mission).kinematics()))

    out = Path(tempfile.mkdtemp(prefix="bench_fly_"))
    port = free_udp_port()
    c0 = _cpu()
    # the mission's kinematics, as fly-mission's embedded vehicle gets them
    veh = subprocess.Popen(
        [sys.executable, "-m", "sitl.vehicle", "--port", str(port), "--speedup", str(speedup)]
        + [
            "--kinematics",
            kin,
        ],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    w0 = time.monotonic()
    fly = subprocess.run(
        [
            sys.executable,
            "-m",
            "mission.cli.fly",
            str(mission),
            "--connect",
            f"udpin://127.0.0.1:{port}",
            "--speedup",
            str(speedup),
            "--out",
            str(out),
            "--no-localize",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    wall = time.monotonic() - w0
    c1 = _cpu()
    veh.terminate()
    veh.wait()
    c2 = _cpu()
    if fly.returncode != 0:
        raise SystemExit(f"flight failed at speed-up {speedup}: {fly.stderr[-2000:]}")
    log = read_flight_log(next(out.glob("*/flight.csv")))
    t = log["t_s"]
    flown_min = (t[-1] - t[0]) / 60.0
    period = float(log.meta["rss_source"].get("sample_period_s", 0.03))
    return {
        "speedup": speedup,
        "rows": len(log),
        "wall_s": wall,
        "rows_per_s": len(log) / wall,
        "coverage": len(log) / ((t[-1] - t[0]) / period + 1),
        "flown_min": flown_min,
        "runner_cpu_s_per_flight_min": (c1 - c0) / flown_min,
        "vehicle_cpu_s_per_flight_min": (c2 - c1) / flown_min,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--speedups", type=float, nargs="+", default=[20.0, 50.0, 100.0])
    p.add_argument("--mission", type=Path, default=ROOT / "missions" / "spiral.yaml")
    a = p.parse_args(argv)
    print(
        f"{'speedup':>8} {'rows':>7} {'wall s':>7} {'rows/s':>8} {'cover':>6} {'flown min':>9} "
        f"{'runner CPU s/min':>16} {'vehicle CPU s/min':>17}"
    )
    for s in a.speedups:
        r = run_one(a.mission, s)
        print(
            f"{r['speedup']:8g} {r['rows']:7d} {r['wall_s']:7.1f} {r['rows_per_s']:8.0f} "
            f"{r['coverage']:6.3f} {r['flown_min']:9.2f} {r['runner_cpu_s_per_flight_min']:16.2f} "
            f"{r['vehicle_cpu_s_per_flight_min']:17.2f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
