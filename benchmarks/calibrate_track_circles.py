"""Calibrate a network's error circles for full *and partial* flights (``track`` in its card's ``sim`` record).

Why (issue 28): an aborted flight (a third of the spiral) printed the full flight's 12 m circle and missed by
51 m.  Normalised conformal prediction: on ``rfsl simulate`` logs of the spiral (the product path: take-off,
return, landing, phase column), each log is cut to the first ``f`` of its mission legs (an abort: ``truncate``),
the network localizes it, and ``training_domain.track_coverage`` measures the share of the planned track flown
(``c``).  Half of the calibration flights (even seeds) fit the exponent ``a`` of ``error ~ c ** -a`` (least
squares on logs); the other half give the conformal quantiles ``q`` of the score ``error * c ** a``; the
circle of a flight that flew ``c`` has radius ``q / c ** a`` (``error_circles.flown_radii``).  Calibration
flights: one full flight and one cut at ``f ~ U(0.2, 1)`` per seed.  The check (held-out seeds) cuts every log
at 1/3, 2/3 and 1 and reports the coverage of the 50 % and 90 % circles per cut.

    python benchmarks/calibrate_track_circles.py --model rfsl_spiral_e2r_ens5 --alts 30 \\
        --seeds 3100:3300 --check-seeds 3400:3460 --write                      # ~10 min on 2 busy cores
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))  # sim_default's simulate_log, mission_variant
LEVELS = (0.5, 0.9)
MIN_FRACTION = 0.2  # calibration cuts are drawn in [0.2, 1]
CHECK_FRACTIONS = (1 / 3, 2 / 3, 1.0)


def truncate(log, fraction: float):
    """The log of a flight aborted after the first ``fraction`` of its mission-phase samples (later mission
    rows dropped; take-off, return and landing rows kept)."""
    ph = np.asarray(log["phase"]).astype(str)
    mission = ph == "mission"
    keep = ~mission | (np.cumsum(mission) <= fraction * mission.sum())
    return log.select(keep)


def _runs(job: tuple[str, str, int, tuple[float, ...]]) -> list[tuple[float, float, float]]:
    """(cut fraction, track coverage, error m) of network ``model`` on one simulated log cut at each fraction
    (``fractions`` empty: one full flight and one cut drawn in [MIN_FRACTION, 1] from the seed)."""
    from sim_default import simulate_log

    from mission.flightlog import read_flight_log
    from mission.localize.api import localize_log

    model, mission, seed, fractions = job
    with tempfile.TemporaryDirectory() as tmp:
        log = read_flight_log(simulate_log(mission, tmp, seed))
    fr = fractions or (1.0, float(np.random.default_rng([seed, 28]).uniform(MIN_FRACTION, 1.0)))
    out = []
    for f in fr:
        est = localize_log(truncate(log, f) if f < 1.0 else log, model_path=str(REPO / "models" / f"{model}.onnx"))
        out.append((f, float(est.extras["track_coverage"]), float(est.error_m)))
    return out


def collect(model: str, missions: list[str], seeds: range, fractions: tuple[float, ...] = ()) -> np.ndarray:
    """(n, 4) rows of seed, cut fraction, track coverage and error over every mission and seed."""
    from rich.progress import track

    from mission.localize.features import one_thread_process

    jobs = [(model, m, s, fractions) for m in missions for s in seeds]
    with ProcessPoolExecutor(2, initializer=one_thread_process) as ex:
        res = list(track(ex.map(_runs, jobs, chunksize=2), total=len(jobs), description=f"{model} flights"))
    return np.array([(j[2], *r) for j, rr in zip(jobs, res, strict=True) for r in rr])


def fit(rows: np.ndarray, source: str) -> dict:
    """The ``track`` record: exponent from the even seeds, conformal radii of the scores of the odd seeds."""
    from mission.localize.error_circles import conformal_radius

    even = rows[:, 0] % 2 == 0
    c, e = np.clip(rows[:, 2], 1e-3, 1.0), np.maximum(rows[:, 3], 1e-3)
    slope = np.polyfit(np.log(c[even]), np.log(e[even]), 1)[0]
    a = float(max(0.0, -slope))
    score = e[~even] * c[~even] ** a
    return {"exponent": round(a, 3), "min_coverage": round(float(np.min(c)), 3),
            "radii_m": {f"{lv:g}": round(conformal_radius(score, lv), 2) for lv in LEVELS},
            "n": int((~even).sum()), "n_fit": int(even.sum()), "calibrated_on": source}


def check(rows: np.ndarray, rec: dict) -> None:
    """Coverage of the circles of ``rec`` on held-out rows, per cut fraction."""
    from mission.localize.error_circles import flown_radii

    rec = {"radii_m": {float(k): v for k, v in rec["radii_m"].items()},
           "track": dict(rec["track"], radii_m={float(k): v for k, v in rec["track"]["radii_m"].items()})}
    for f in sorted(set(rows[:, 1])):
        sel = rows[rows[:, 1] == f]
        hits: dict = {0.5: [], 0.9: [], "r": []}
        for _, _, cov, err in sel:
            radii, _ = flown_radii(rec, cov)
            if radii is None:
                continue
            hits["r"].append(radii[0.9])
            for lv in LEVELS:
                hits[lv].append(err <= radii[lv])
        n = len(hits["r"])
        print(f"  cut {f:.2f} (track coverage {np.median(sel[:, 2]):.2f}; n={len(sel)}, circles {n}): mean error "
              f"{sel[:, 3].mean():.1f} m, in 50 % / 90 %: {100 * np.mean(hits[0.5]):.1f} / "
              f"{100 * np.mean(hits[0.9]):.1f} %, median 90 % radius {np.median(hits['r']):.1f} m", flush=True)


def main() -> None:
    from sim_default import mission_variant

    from mission.localize.error_circles import model_digest

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default="rfsl_spiral_e2r_ens5")
    ap.add_argument("--alts", nargs="+", type=float, default=[30.0], help="spiral cruise altitudes (m)")
    ap.add_argument("--seeds", default="3100:3300", help="calibration seeds first:last")
    ap.add_argument("--check-seeds", default="3400:3460", help="held-out seeds first:last")
    ap.add_argument("--write", action="store_true", help="store the record in the card's 'sim' calibration")
    ap.add_argument("--check-only", action="store_true", help="check the card's stored record, calibrate nothing")
    args = ap.parse_args()
    card = REPO / "models" / f"{args.model}.json"
    d = json.loads(card.read_text())
    sim = d["regions"]["sim"]
    if sim.get("model_sha256") != model_digest(REPO / "models" / f"{args.model}.onnx"):
        sys.exit(f"{card.name}: its sim calibration was measured on another model file")
    with tempfile.TemporaryDirectory() as tmp:
        missions = [mission_variant(str(REPO / "missions/spiral.yaml"), tmp, f"{a:g} m", None if a == 30 else a)
                    for a in args.alts]
        lo, hi = (int(v) for v in args.seeds.split(":"))
        if args.check_only:
            lo = hi = 0
        rows = collect(args.model, missions, range(lo, hi)) if hi > lo else None
        if rows is None and "track" not in sim:
            sys.exit(f"{card.name} has no track calibration to check")
        alts = ", ".join(f"{a:g}" for a in args.alts)
        if rows is not None:
            rec = fit(rows, f"rfsl simulate spirals at {alts} m, seeds {lo}-{hi - 1}, each full and cut at "
                            f"U({MIN_FRACTION}, 1) of its mission legs")
            print(args.model, json.dumps(rec), flush=True)
            full = rows[rows[:, 1] == 1.0]
            print(f"  calibration: full flights mean {full[:, 3].mean():.1f} m, partial "
                  f"{rows[rows[:, 1] < 1.0][:, 3].mean():.1f} m", flush=True)
            sim = dict(sim, track=rec)
        if args.write and rows is not None:
            d["regions"]["sim"] = sim
            card.write_text(json.dumps(d, indent=1) + "\n")
        lo, hi = (int(v) for v in args.check_seeds.split(":"))
        if hi > lo:
            print(f"held out, seeds {lo}-{hi - 1}:")
            check(collect(args.model, missions, range(lo, hi), CHECK_FRACTIONS), sim)


if __name__ == "__main__":
    main()
