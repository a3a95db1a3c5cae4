"""Calibrate a network's error circles for full *and partial* flights (``track`` in its card's
``sim`` record).

Why: an aborted flight (a third of the spiral) printed the full flight's 12 m circle and missed by
51 m.  Mondrian (stratified) conformal prediction: on ``rfsl simulate`` logs of the spiral (the
product path: take-off, return, landing, phase column), each log is cut to the first ``f`` of its
mission legs (an abort: ``truncate``), the network localizes it, and
``training_domain.track_coverage`` measures the share of the planned track flown (``c``).  The
flights are split into strata of ``c`` (from the lowest seen, 0.5, 0.9) and each stratum's circles
are the conformal radii of its own errors (``error_circles.flown_radii``).  Flights: per ``--seeds``
seed one full flight and one cut at ``f ~ U(0.2, 1)``; per ``--check-seeds`` seed cuts at 1/3, 2/3
and 1.  Coverage is reported held out: 5-fold over seeds (each fold's circles fitted on the other
folds), per kind of cut.  A power law ``error ~ c ** -a`` (normalised conformal) was tried first and
under-covered the 2/3 cuts (78 % at 90 %): errors do not scale as one power of the coverage.

    # ~20 min on 2 busy cores
    python benchmarks/calibrate_track_circles.py --model rfsl_spiral_e2r_ens5 --alts 30 \\
        --seeds 3100:3300 --check-seeds 3400:3460 --rows /tmp/track.npy --write
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from rich.progress import track

from mission.evidence import conformal_quantile
from mission.flightlog import read_flight_log
from mission.localize.api import localize_log
from mission.localize.error_circles import flown_radii, model_digest
from mission.threads import limit_worker

# sim_default's simulate_log, mission_variant
sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_default import mission_variant, simulate_log

REPO = Path(__file__).resolve().parent.parent

LEVELS = (0.5, 0.9)
MIN_FRACTION = 0.2  # calibration cuts are drawn in [0.2, 1]
# coverage strata above the lowest calibrated coverage: < 0.5, 0.5-0.9, full (>= 0.9)
STRATA = (
    0.5,
    0.9,
)
CHECK_FRACTIONS = (1 / 3, 2 / 3, 1.0)


def truncate(log, fraction: float):
    """The log of a flight aborted after the first ``fraction`` of its mission-phase samples (later
    mission rows dropped; take-off, return and landing rows kept)."""
    ph = np.asarray(log["phase"]).astype(str)
    mission = ph == "mission"
    keep = ~mission | (np.cumsum(mission) <= fraction * mission.sum())
    return log.select(keep)


def _runs(job: tuple[str, str, int, tuple[float, ...]]) -> list[tuple[float, float, float]]:
    """(cut fraction, track coverage, error m) of network ``model`` on one simulated log cut at each
    fraction (``fractions`` empty: one full flight and one cut drawn in [MIN_FRACTION, 1] from the
    seed)."""
    model, mission, seed, fractions = job
    with tempfile.TemporaryDirectory() as tmp:
        log = read_flight_log(simulate_log(mission, tmp, seed))
    fr = fractions or (1.0, float(np.random.default_rng([seed, 28]).uniform(MIN_FRACTION, 1.0)))
    out = []
    for f in fr:
        est = localize_log(
            truncate(log, f) if f < 1.0 else log, model_path=str(REPO / "models" / f"{model}.onnx")
        )
        out.append((f, float(est.extras["track_coverage"]), float(est.error_m)))
    return out


def collect(
    model: str, missions: list[str], seeds: range, fractions: tuple[float, ...] = ()
) -> np.ndarray:
    """(n, 4) rows of seed, cut fraction, track coverage and error over every mission and seed."""
    jobs = [(model, m, s, fractions) for m in missions for s in seeds]
    with ProcessPoolExecutor(2, initializer=limit_worker) as ex:
        res = list(
            track(ex.map(_runs, jobs, chunksize=2), total=len(jobs), description=f"{model} flights")
        )
    return np.array([(j[2], *r) for j, rr in zip(jobs, res, strict=True) for r in rr])


def stratum(c: np.ndarray, bounds: list[float]) -> np.ndarray:
    """Index of each coverage's stratum (-1 below the first bound)."""
    return np.searchsorted(bounds, c, side="right") - 1


def fit(rows: np.ndarray, source: str) -> dict:
    """The ``track`` record: per coverage stratum (from the lowest coverage seen, 0.5, 0.9) the
    conformal radii of the errors of the flights in it."""
    bounds = [round(float(np.min(rows[:, 2])) - 0.005, 2), *STRATA]
    k = stratum(rows[:, 2], bounds)
    return {
        "bounds": bounds,
        "radii_m": {
            f"{lv:g}": [
                round(conformal_quantile(rows[k == s, 3], lv), 2) for s in range(len(bounds))
            ]
            for lv in LEVELS
        },
        "n": [int((k == s).sum()) for s in range(len(bounds))],
        "calibrated_on": source,
    }


def cross_validate(rows: np.ndarray, folds: int = 5) -> None:
    """Coverage of the circles fitted without each fold of seeds, on that fold: per cut kind (1/3,
    2/3, random cuts, full flights)."""
    seeds = np.unique(rows[:, 0])
    parts = np.array_split(np.random.default_rng(0).permutation(seeds), folds)
    got: dict = {}
    for f in parts:
        test = np.isin(rows[:, 0], f)
        tr = fit(rows[~test], "")
        rec = {
            "radii_m": {},
            "track": dict(tr, radii_m={float(k): v for k, v in tr["radii_m"].items()}),
        }
        for _, cut, cov, err in rows[test]:
            kind = (
                "cut 1/3"
                if np.isclose(cut, 1 / 3)
                else "cut 2/3"
                if np.isclose(cut, 2 / 3)
                else "full"
                if cut == 1.0
                else "cut U(0.2, 1)"
            )
            radii, _ = flown_radii(rec, cov)
            for lv in LEVELS:
                got.setdefault((kind, lv), []).append(radii is not None and err <= radii[lv])
            got.setdefault((kind, "r"), []).append(radii[0.9] if radii else np.inf)
    for kind in ("cut 1/3", "cut 2/3", "cut U(0.2, 1)", "full"):
        if (kind, 0.5) in got:
            print(
                f"  {kind} (n={len(got[kind, 0.5])}): in 50 % / 90 %: "
                f"{100 * np.mean(got[kind, 0.5]):.1f} / "
                f"{100 * np.mean(got[kind, 0.9]):.1f} %, median 90 % radius "
                f"{np.median(got[kind, 'r']):.1f} m",
                flush=True,
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default="rfsl_spiral_e2r_ens5")
    ap.add_argument(
        "--alts", nargs="+", type=float, default=[30.0], help="spiral cruise altitudes (m)"
    )
    ap.add_argument("--seeds", default="3100:3300", help="calibration seeds first:last")
    ap.add_argument(
        "--check-seeds", default="3400:3460", help="seeds cut at 1/3, 2/3 and 1 (first:last)"
    )
    ap.add_argument(
        "--write", action="store_true", help="store the record in the card's 'sim' calibration"
    )
    ap.add_argument(
        "--rows",
        help="keep the calibration rows in this .npy, the check's in .check.npy (reused "
        "when they exist)",
    )
    args = ap.parse_args()
    card = REPO / "models" / f"{args.model}.json"
    d = json.loads(card.read_text())
    sim = d["regions"]["sim"]
    if sim.get("model_sha256") != model_digest(REPO / "models" / f"{args.model}.onnx"):
        sys.exit(f"{card.name}: its sim calibration was measured on another model file")
    with tempfile.TemporaryDirectory() as tmp:
        missions = [
            mission_variant(
                str(REPO / "missions/spiral.yaml"), tmp, f"{a:g} m", None if a == 30 else a
            )
            for a in args.alts
        ]
        sets = []
        for seeds, fractions, cache in (
            (args.seeds, (), args.rows),
            (
                args.check_seeds,
                CHECK_FRACTIONS,
                args.rows and str(Path(args.rows).with_suffix(".check.npy")),
            ),
        ):
            lo, hi = (int(v) for v in seeds.split(":"))
            if cache and Path(cache).is_file():
                sets.append(np.load(cache))
            elif hi > lo:
                sets.append(collect(args.model, missions, range(lo, hi), fractions))
                if cache:
                    np.save(cache, sets[-1])
    rows = np.vstack(sets)
    alts = ", ".join(f"{a:g}" for a in args.alts)
    rec = fit(
        rows,
        f"{len(rows)} rfsl simulate spirals at {alts} m, full and cut short (seeds {args.seeds}, "
        f"{args.check_seeds})",
    )
    print(args.model, json.dumps(rec), flush=True)
    print("held out, 5-fold over seeds:")
    cross_validate(rows)
    if args.write:
        d["regions"]["sim"] = dict(sim, track=rec)
        card.write_text(json.dumps(d, indent=1) + "\n")


if __name__ == "__main__":
    main()
