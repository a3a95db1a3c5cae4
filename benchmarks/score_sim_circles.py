"""A network's error circles on simulated logs, applied only inside its training attitudes: a rule
written before scoring (the house rule that every estimate carries an honest uncertainty).

Why: the spiral networks' ``sim`` circles were calibrated on ``rfsl simulate`` spirals flown by the
built-in vehicle, which cruises nearly level. On a simulated log they are vetoed only when the
flight's pitch (5-95 %) leaves the training's span (1-99 %) by more than 5 deg
(``training_domain.ATTITUDE_TOLERANCE_DEG``): PX4 SITL (-30 to -9 deg against -13 to 10 deg) gets
the self-calibrating posterior's regions, but ArduCopter SITL (-15 deg at its 5 %, 2 deg beyond)
keeps the circles. Found this stop (after the adaptive regions' rule, ``score_adaptive_regions.py
sitl``'s companion run on the fixed flights): on the 18 fixed ArduCopter flights on disk the network
erred 13.7 m at the median, and its 90 % circle (9.5 m) held the truth on 8 of them, its 50 % circle
on 6.

Rule (written 2026-11-28 20:03 UTC, before any flight was localized with the change; the 18 flights
above and the PX4 ones are the finding, not the test):
- Change: on simulated logs the circles apply only where the flown roll and pitch (5-95 %) lie
  inside the training's 1-99 % span with no tolerance
  (``training_domain.CIRCLE_ATTITUDE_TOLERANCE_DEG`` = 0); otherwise the existing fallback, the
  self-calibrating posterior's regions, with the note. Real logs are untouched (their attitude
  check is a note, with the 5 deg tolerance).
- Adopted if both hold:
  1. the product path's simulated spirals (``rfsl simulate`` of ``missions/spiral.yaml``, seeds
     7000-7099, the set ``benchmarks/sim_default.py`` scores) keep their circles on at least 98 of
     100 flights;
  2. on ten ArduCopter SITL fixed flights never flown (``bench_sitl_seeds.py --autopilot ardupilot
     --arms fixed --seeds 15 ... 24``, 20x), the printed regions' worst |coverage - nominal| over
     the 50 % and 90 % levels is smaller with the change than with today's tolerance, on the same
     logs.
Reported beside: the 33 fixed SITL flights on disk (both autopilots), with each tolerance.

Result (2026-11-28): adopted (models/README.md, "Circles inside the training attitudes").
1. Product-path spirals 7000-7099: 100 of 100 keep their circles (today 100).
2. ArduCopter SITL seeds 15-24 (every flight exit 0; the network erred 6.6-46.2 m): today's
   circles held 0 / 10 at 50 % and 1 / 10 at 90 % (worst 80 points); with the change the
   posterior's regions hold 6 / 10 and 10 / 10 (worst 10 points).
Beside: the 18 ArduCopter flights on disk 6 / 18, 8 / 18 -> 8 / 18, 18 / 18; the 15 PX4 flights
unchanged (6 / 15, 15 / 15: their pitch was already outside by more than 5 deg).

    python benchmarks/score_sim_circles.py product --seeds 7000:7100
    python benchmarks/score_sim_circles.py sitl D/flights.jsonl [...]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sitl_seeds import stored_flights  # noqa: E402
from sim_default import simulate_log  # noqa: E402

import mission.localize.api as api  # noqa: E402
from mission.flightlog import read_flight_log  # noqa: E402
from mission.localize.region import CIRCLE  # noqa: E402
from mission.localize.training_domain import ATTITUDE_TOLERANCE_DEG  # noqa: E402
from mission.threads import limit_worker  # noqa: E402
from mission.workshop.evaluate_suite import region_coverage  # noqa: E402

TOLERANCES = {"today": ATTITUDE_TOLERANCE_DEG, "change": 0.0}
LEVELS = ("50", "90")


def answered(log, tolerance_deg: float) -> tuple[object, bool, dict]:
    """(estimate, whether its regions are error circles, coverage by level) of ``localize``'s
    default on ``log`` with the circles' attitude tolerance ``tolerance_deg``."""
    api.CIRCLE_ATTITUDE_TOLERANCE_DEG = tolerance_deg
    est = api.localize_log(log)
    circles = bool(est.regions) and all(r.kind == CIRCLE for r in est.regions)
    return est, circles, region_coverage(est, log.truth_enu[:2])


def _product_one(job: tuple[int, str]) -> dict:
    seed, out = job
    log = read_flight_log(simulate_log("missions/spiral.yaml", out, seed))
    return {k: answered(log, t)[1] for k, t in TOLERANCES.items()}


def product(first: int, last: int, workers: int) -> bool:
    """Condition 1: the share of product-path spirals that keep their circles."""
    with tempfile.TemporaryDirectory() as out:
        jobs = [(s, out) for s in range(first, last)]
        with ProcessPoolExecutor(workers, initializer=limit_worker) as ex:
            rows = list(ex.map(_product_one, jobs))
    keep = {k: sum(r[k] for r in rows) for k in TOLERANCES}
    n = len(rows)
    print(
        f"product-path spirals keeping their circles: today {keep['today']}/{n}, change "
        f"{keep['change']}/{n}"
    )
    ok = keep["change"] >= 0.98 * n
    print(f"condition 1: {ok}")
    return ok


def _worst(cov: dict[str, list[bool]]) -> float:
    return max(abs(100 * sum(cov[k]) / len(cov[k]) - float(k)) for k in LEVELS)


def sitl(stores: list[Path]) -> bool:
    """Condition 2 on the fixed flights of the stores: coverage of the printed regions with each
    tolerance."""
    by = {}
    for r, log in stored_flights(stores, "fixed"):
        cells = []
        for name, t in TOLERANCES.items():
            est, circles, cov = answered(log, t)
            d = by.setdefault((r["autopilot"], name), {k: [] for k in LEVELS} | {"n_c": 0})
            for k in LEVELS:
                d[k].append(bool(cov[k]))
            d["n_c"] += circles
            reg = est.region(0.9)
            cells.append(
                f"{name} {'circle' if circles else 'posterior'} "
                f"{int(cov['50'])}{int(cov['90'])} {reg.area_m2:.0f} m^2"
            )
        print(
            f"{r['autopilot']:9s} seed {r['seed']:2d} error {est.error_m:5.1f} m: "
            + "; ".join(cells)
        )
    ok = True
    for (ap, name), d in sorted(by.items()):
        n = len(d["50"])
        print(
            f"{ap:9s} {name:6s}: circles {d['n_c']}/{n}, 50 % {sum(d['50'])}/{n}, 90 % "
            f"{sum(d['90'])}/{n}, worst {_worst(d):.0f} points"
        )
    for ap in sorted({a for a, _ in by}):
        better = _worst(by[ap, "change"]) < _worst(by[ap, "today"])
        print(f"{ap}: worst deviation smaller with the change: {better}")
        ok = ok and better
    return ok


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    pr = sub.add_parser("product")
    pr.add_argument("--seeds", default="7000:7100")
    pr.add_argument("--workers", type=int, default=2)
    st = sub.add_parser("sitl")
    st.add_argument("stores", nargs="+", type=Path)
    a = p.parse_args(argv)
    if a.cmd == "product":
        lo, hi = (int(v) for v in a.seeds.split(":"))
        product(lo, hi, a.workers)
    else:
        sitl(a.stores)
    return 0


if __name__ == "__main__":
    sys.exit(main())
