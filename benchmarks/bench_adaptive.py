"""Adaptive finish vs the fixed spiral at equal flight budget, on the fast simulator under a physics
family.

    # a few minutes on 2 cores
    nice -n 10 python benchmarks/bench_adaptive.py --flights 40 --jobs 2
    # a variant of the adaptive block
    python benchmarks/bench_adaptive.py --flights 4 --set altitude_m=15
    # a vehicle that cruises nose down as ArduCopter SITL does (-15 deg at 5.5 m/s; PX4: 5.6)
    python benchmarks/bench_adaptive.py --family mission --vehicle drag_pitch_deg_per_mps=2.8

Each flight i draws its physics from the family (``load_family``; ``afar`` by default, a fitted JSON
later), its transmitter uniformly in the rover area and one shadowing map
(``simflight.FlightWorld``, seed ``SeedSequence(seed, spawn_key=(i,))``); the fixed mission (the
whole spiral) and the adaptive one (its first ``survey_s`` s, then rounds planned from the live
estimate) fly in that same world within the same 10-minute budget, and each is scored by what
``localize`` answers for it after landing (``compare.product_answer``: the spiral network on the
fixed spiral, the live method on the adaptive flight), the live estimator's errors on both beside.
Reported: mean error with its bootstrap 90 % interval, the paired difference adaptive - fixed with
its interval (``mission.evidence``), p90 error, 90 % region coverage and area, flight time, and the
3-minute (fast) estimate, identical for both while the survey lasts at least 3 minutes.

Rule written before scoring: the adaptive finish "halves the error" only if its mean is at most half
the fixed spiral's and the paired interval of the difference excludes zero; otherwise the table says
what it reached.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rich.progress import track

from mission.adaptive.compare import pair, summarize_pairs
from mission.spec import load_mission
from mission.trajectory.multicopter import Kinematics


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _assignments(items: list[str]) -> dict:
    """``KEY=VALUE`` options as a dict, each value read as JSON where it parses (``_value``)."""
    return {k: _value(v) for k, v in (s.split("=", 1) for s in items)}


def one_flight(args: tuple) -> dict:
    """Fixed and adaptive versions of flight ``i`` (run in a worker)."""
    mission, family, seed, i, dt, sets, vehicle = args

    spec = load_mission(mission)
    return pair(spec, dataclasses.replace(spec.adaptive, **sets), family, seed, i, dt, vehicle)


def table(rows: list[dict]) -> str:
    s = summarize_pairs(rows)
    lines = [
        f"{s['n']} flights (of {s['n_total']}); 90 % bootstrap intervals over flights",
        "| mission | mean error m | adaptive - fixed m | p90 m | 90 % coverage | region m^2 "
        "(median) | flight s "
        "| rounds |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for k in ("fixed", "adaptive"):
        r = s[k]
        diff = "-" if k == "fixed" else r["diff"].fmt()
        lines.append(
            f"| {k} | {r['mean'].fmt()} | {diff} | {r['p90_m']:.1f} | "
            f"{100 * r['coverage']:.0f} % | "
            f"{r['area_m2']:.0f} | {r['duration_s']:.0f} | {r['rounds']:.1f} |"
        )
    meth = ", ".join(f"{k} by {'/'.join(s['methods'][k])}" for k in ("fixed", "adaptive"))
    lines.insert(1, f"errors of what localize answers after landing ({meth})")
    if "live" in s:
        lv = s["live"]
        lines.append(
            f"live estimator on both ({lv['n']} flights): fixed {lv['fixed']['mean'].fmt()} m, "
            f"adaptive {lv['adaptive']['mean'].fmt()} m, paired {lv['adaptive']['diff'].fmt()} m"
        )
        lines.append(
            f"adaptive answer - its live estimate (paired): {s['answer_vs_live']['diff'].fmt()} m"
        )
    if s["fast"]:
        lines.append(
            f"fast estimate (3 min, same survey for both): mean {s['fast'][0].fmt()} m, "
            f"p90 {s['fast'][1]:.1f} m"
        )
    halves = s["ratio"] <= 0.5 and s["adaptive"]["diff"].hi < 0
    lines.append(
        f"adaptive / fixed mean error = {s['ratio']:.2f}: "
        f"{'halves' if halves else 'does not halve'} the "
        "fixed spiral's error (rule: ratio <= 0.5 and the paired interval below zero)"
    )
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mission", default="missions/spiral_adaptive.yaml")
    p.add_argument(
        "--family",
        default="afar",
        help="physics family: a shipped name, a fitted JSON file, or 'mission' (the mission's own "
        "source model without shadowing: what fly-mission simulates against a SITL)",
    )
    p.add_argument("--flights", type=int, default=40)
    p.add_argument("--seed", type=int, default=2025)
    p.add_argument(
        "--dt",
        type=float,
        default=None,
        help="RSS sample period s (default: the mission's own, 0.03 s, what fly-mission logs; "
        "0.1, the default before 2026-11-29, is 3x faster but handicaps the networks, trained at "
        "the mission's period: docs/adaptive.md)",
    )
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override an adaptive: key"
    )
    p.add_argument(
        "--vehicle",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a Kinematics field of the simulated vehicle, e.g. "
        "drag_pitch_deg_per_mps=2.8 (cruise at -15 deg of pitch at the mission's 5.5 m/s, as "
        "ArduCopter SITL does)",
    )
    p.add_argument("--json", type=Path, help="write the per-flight results")
    a = p.parse_args(argv)
    sets, vehicle = _assignments(a.set), _assignments(a.vehicle)
    known = {f.name for f in dataclasses.fields(Kinematics)}
    if set(vehicle) - known:
        p.error(
            f"--vehicle: unknown field(s) {sorted(set(vehicle) - known)} (known: {sorted(known)})"
        )
    jobs = [(a.mission, a.family, a.seed, i, a.dt, sets, vehicle) for i in range(a.flights)]

    with ProcessPoolExecutor(a.jobs) as ex:
        rows = list(
            track(ex.map(one_flight, jobs), total=len(jobs), description="flights", transient=True)
        )
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    period = "the mission's" if a.dt is None else f"{a.dt:g} s"
    print(
        f"mission {a.mission}, family {a.family}, seed {a.seed}, adaptive overrides "
        f"{sets or 'none'}, vehicle {vehicle or 'as the mission'}, sample period {period}"
    )
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
