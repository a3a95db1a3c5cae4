"""Posterior-predictive checks with the design held: a family's flights along the six real tracks.

The benchmark's predictive checks (``score_decision.py``) compare the real flights with flights of
other tracks and other transmitter positions (a third outside the flight area, a quarter on random
paths), so a failed error check may say "the benchmark's geometry is harder", not "the physics is
wrong".  Here each real flight is simulated again ``--k`` times along its own track and attitude
with its own transmitter, each copy's physics a fresh draw of the family
(``mission.gap.loopcheck``'s way: ``family.draw`` then ``simulate_rss``; rows the receiver did not
log stay empty), and scored exactly as the real flight is (the same methods, the grid's physics
fitted on the other team). Each statistic and each method's error is then a ``design_check``
(``mission.workshop.predictive``): the predictive p of the real mean among means of one copy per
flight, passing inside [0.05, 0.95].

Rule (written 2026-11-27 22:20 UTC, before any copy was scored): run for the shipped family
(``afar``) and for the family with per-flight structure (issue 34 item 4: ``bench_gap.py speed
--jobs family --family-structure --family-out F.json``), 20 copies per flight, seed 0. The family
that passes more of the 13 checks fits the real flights better with their design held; a tie says
neither. This decides no swap of the shipped family (models/README.md's rule asks for every
calibrated figure re-measured on a new family first); it says which family those re-measurements
should be made on.

    python benchmarks/ppc_same_design.py --mat ../shared/data/afar2023/mat --family afar --k 20 \
        --workers 2 --json /tmp/ppc_afar.json

``--lock-losses`` draws the AFAR sounder's lock losses into every copy (stop 58; ``replicate``).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from rich.console import Console
from rich.progress import track
from score_decision import methods, real_kwargs

from mission.flightlog import FlightLog, read_flight_log
from mission.importers.afar import AFAR2023_TRUTH, import_afar_mat
from mission.localize.api import localize_log
from mission.physics.family import load_family, simulate_rss
from mission.workshop.predictive import STATISTICS, design_check, flight_statistics, verdict

MODELS = Path(__file__).resolve().parents[1] / "models"


# the AFAR sounder's lock (experiments/lock_mechanism.py, the six flights' cruise samples): each
# flight's floor (mpower dB, the families' scale) and what it reads out of lock, relative to it
LOCK_FLOOR_DB = (-21.6, 5.1)  # mean, sd over the six flights
OUT_OF_LOCK_READ_DB = (-4.8, 6.5)  # pooled mean, sd of reading - floor


def replicate(
    log: FlightLog, family, rng: np.random.Generator, lock_losses: bool = False
) -> FlightLog:
    """``log`` with its RSS simulated again under one draw of ``family`` (same rows, track,
    attitude, transmitter; rows without RSS stay without).  ``lock_losses``: after the draw, a
    floor from ``LOCK_FLOOR_DB``; a sample under it reads the floor plus ``OUT_OF_LOCK_READ_DB``
    (the sounder out of lock: no hysteresis, so sample by sample)."""
    draw = family.draw(rng)
    att = log.attitude_rad
    enu = log.enu()
    att = np.zeros_like(enu) if att is None else np.nan_to_num(att)
    rss = simulate_rss(draw, log.truth_enu, enu, att, rng)
    rss[~np.isfinite(log["rss_dbm"])] = np.nan
    if lock_losses:
        floor = rng.normal(*LOCK_FLOOR_DB)
        lost = np.isfinite(rss) & (rss < floor)
        rss[lost] = floor + rng.normal(*OUT_OF_LOCK_READ_DB, size=int(lost.sum()))
    return FlightLog({**log.columns, "rss_dbm": rss}, dict(log.meta), log.path, [])


def score(log: FlightLog, team: str, specs: dict[str, str]) -> tuple[dict, dict[str, float]]:
    """(check statistics, {method label: error m}) of one flight, scored as the real ones are."""
    truth = log.truth_enu
    stats = flight_statistics(log, truth[:2], float(truth[2]))
    errs = {}
    for label, spec in specs.items():
        est = localize_log(log, **real_kwargs(spec, team))
        errs[label] = float(np.hypot(est.x_m - truth[0], est.y_m - truth[1]))
    return stats, errs


def _copy(job: tuple) -> tuple[int, int, dict, dict]:
    path, team, family, seed, i, k, specs, lock_losses = job
    log = read_flight_log(path)
    rep = replicate(log, load_family(family), np.random.default_rng([seed, i, k]), lock_losses)
    stats, errs = score(rep, team, specs)
    return i, k, stats, errs


def real_flights(mat: str, tmp: str) -> list[tuple[str, str, str]]:
    """(name, team, imported log path) of the six shared flights."""
    out = []
    for f in sorted(Path(mat).glob("results_useful_ori_exp_*_loc_*.mat")):
        name = f.stem.replace("results_useful_ori_exp_", "")
        loc = int(name.rsplit("_", 1)[1])
        out.append(
            (name, name.split("_")[0], str(import_afar_mat(f, tmp, AFAR2023_TRUTH[loc]).out_path))
        )
    if not out:
        raise SystemExit(f"no AFAR MAT files under {mat}")
    return out


def design_parser(description: str, k: int, json_help: str) -> argparse.ArgumentParser:
    """The arguments of a script that draws a family's copies of the six real flights."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--mat", required=True, help="folder of the AFAR 2023 .mat files")
    ap.add_argument("--family", default="afar", help="a shipped family name or a family JSON")
    ap.add_argument("--k", type=int, default=k, help="copies (family draws) per real flight")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", help=json_help)
    return ap


def main() -> None:
    ap = design_parser(
        __doc__.splitlines()[0], 20, "write the checks and every copy's figures here"
    )
    ap.add_argument(
        "--lock-losses",
        action="store_true",
        help="draw the AFAR sounder's lock losses into each copy (``replicate``)",
    )
    a = ap.parse_args()
    specs = methods(MODELS, [])
    con = Console(width=80)
    with tempfile.TemporaryDirectory() as tmp:
        flights = real_flights(a.mat, tmp)
        real = [score(read_flight_log(p), team, specs) for _, team, p in flights]
        jobs = [
            (p, team, a.family, a.seed, i, k, specs, a.lock_losses)
            for i, (_, team, p) in enumerate(flights)
            for k in range(a.k)
        ]
        with get_context("spawn").Pool(a.workers) as pool:
            done = list(
                track(pool.imap_unordered(_copy, jobs), total=len(jobs), description="copies")
            )
    sims = [[None] * a.k for _ in flights]
    for i, k, stats, errs in done:
        sims[i][k] = (stats, errs)
    checks = {
        s: design_check([r[0][s] for r in real], [[c[0][s] for c in row] for row in sims])
        for s in STATISTICS
    }
    for label in specs:
        checks[f"error m: {label}"] = design_check(
            [r[1][label] for r in real], [[c[1][label] for c in row] for row in sims]
        )
    lock = ", lock losses drawn" if a.lock_losses else ""
    con.print(f"family {a.family}, {a.k} copies per flight, seed {a.seed}{lock}")
    for name, c in checks.items():
        con.print(
            f"{name[:34]:34} real {c['real_mean']:6.1f} copies {c['sim_mean']:6.1f} "
            f"in {c['inside']}/{c['n_real']} p {c['p']:.2f} {'yes' if c['passes'] else 'NO'}"
        )
    con.print(verdict(checks))
    if a.json:
        Path(a.json).write_text(
            json.dumps(
                {
                    "family": a.family,
                    "k": a.k,
                    "seed": a.seed,
                    "flights": [n for n, _, _ in flights],
                    "checks": checks,
                    "real": real,
                    "copies": sims,
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
