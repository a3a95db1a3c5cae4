"""The SITL flights' transmitters flown again in the fast simulator: does it show, on the same
transmitters, what the SITLs showed?

    python benchmarks/sitl_vs_fast.py AC/flights.jsonl PX4/flights.jsonl [--reps 3]

Why: the fast simulator decided questions about the adaptive finish (``bench_adaptive.py``) whose
answers did not hold on the SITLs (docs/adaptive.md, "Finish the spiral when the survey answers
beyond the fence?").  Each fixed/adaptive SITL pair of ``bench_sitl_seeds.py``'s store is flown
``--reps`` times by ``adaptive.compare.pair`` with the pair's own transmitter (its sidecar's truth),
the mission's physics and the vehicle cruising nose down as that autopilot does
(``drag_pitch_deg_per_mps`` 2.8 for ArduCopter, -15 deg; 5.6 for PX4, -28 deg); both are scored
by what ``localize`` answers.  Printed: per seed the SITL's and the fast simulator's mean errors,
then per autopilot the paired differences fast - SITL for each arm and adaptive - fixed on each.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from mission.evidence import paired_difference  # noqa: E402

DRAG = {"ardupilot": 2.8, "px4": 5.6}  # deg of pitch per m/s: the autopilots' cruise


def fly(job: tuple) -> tuple:
    """(autopilot, seed, fixed error, adaptive error) of one fast-simulator pair flown with the
    SITL pair's transmitter ``tx``."""
    autopilot, seed, tx, rep, dt = job
    from mission.adaptive import compare  # noqa: PLC0415
    from mission.spec import load_mission  # noqa: PLC0415

    class World(compare.FlightWorld):  # the SITL pair's transmitter, the rest drawn as ever
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            self.tx = np.asarray(tx, dtype=float)

    compare.FlightWorld = World
    spec = load_mission(ROOT / "missions" / "spiral_adaptive.yaml")
    vehicle = {"drag_pitch_deg_per_mps": DRAG[autopilot]}
    r = compare.pair(spec, spec.adaptive, "mission", 9100 + rep, seed, dt_s=dt, vehicle=vehicle)
    return autopilot, seed, r["fixed"]["error_m"], r["adaptive"]["error_m"]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("stores", nargs="+", type=Path, help="bench_sitl_seeds.py flights.jsonl")
    p.add_argument("--reps", type=int, default=3, help="fast-simulator flights per pair")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--dt", type=float, help="RSS sample period s (default: the mission's)")
    args = p.parse_args(argv)
    sitl: dict[tuple, dict] = {}
    jobs = []
    for store in args.stores:
        for r in (json.loads(ln) for ln in store.read_text().splitlines() if ln.strip()):
            sitl.setdefault((r["autopilot"], r["seed"]), {})[r["arm"]] = r
    for (autopilot, seed), arms in sorted(sitl.items()):
        if {"fixed", "adaptive"} <= set(arms) and None not in (
            arms["fixed"]["error_m"],
            arms["adaptive"]["error_m"],
        ):
            side = Path(arms["fixed"]["log"]).with_suffix(".json")
            t = json.loads(side.read_text())["truth"]
            tx = [t["x_m"], t["y_m"], t.get("z_m", 1.5)]
            jobs += [(autopilot, seed, tx, rep, args.dt) for rep in range(args.reps)]
    fast: dict[tuple, list] = {}
    with ProcessPoolExecutor(args.jobs) as ex:
        for autopilot, seed, f, a in ex.map(fly, jobs):
            if None not in (f, a):
                fast.setdefault((autopilot, seed), []).append((f, a))
    rows = []
    for key, v in sorted(fast.items()):
        s, m = sitl[key], np.mean(v, axis=0)
        rows.append((key[0], s["fixed"]["error_m"], s["adaptive"]["error_m"], m[0], m[1]))
        print(
            f"{key[0]:9s} seed {key[1]:3d}: SITL fixed {s['fixed']['error_m']:5.1f}, adaptive "
            f"{s['adaptive']['error_m']:5.1f} m; fast {m[0]:5.1f}, {m[1]:5.1f} m"
        )
    for autopilot in sorted({r[0] for r in rows}):
        sf, sa, ff, fa = np.array([r[1:] for r in rows if r[0] == autopilot]).T
        print(f"{autopilot} ({len(sf)} transmitters, {args.reps} fast flights each):")
        print(f"  fixed, fast - SITL     {paired_difference(ff, sf, seed=1).fmt()} m")
        print(f"  adaptive, fast - SITL  {paired_difference(fa, sa, seed=1).fmt()} m")
        print(
            f"  adaptive - fixed: SITL {paired_difference(sa, sf, seed=1).fmt()} m, fast "
            f"{paired_difference(fa, ff, seed=1).fmt()} m"
        )


if __name__ == "__main__":
    main()
