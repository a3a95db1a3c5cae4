"""Calibrate the self-calibrating posterior's HPD masses on the unseen-flight benchmark
(``selfcal.CALIBRATED_MASS``).

Why: the tempered likelihood is not an exact posterior, so an HPD set of mass 0.9 need not hold the
truth 90 % of the time.  For every benchmark flight the truth's HPD level ``q``
(``Posterior.hpd_level``: the mass of the cells more probable than the truth's) is recorded; the set
of mass M covers the truth exactly when ``q < M``, so the 50th / 90th percentiles of ``q`` over the
flights are the masses that cover at the nominal rates.  Printed with the coverage per seed,
leave-one-seed-out and 5-fold (seeded) cross-validated coverage.

Usage (the shipped masses: three seeds of the ``afar`` family, 500 flights, 33 s on 2 cores)::

    python benchmarks/calibrate_regions.py --seeds 2026:200 2027:100 2028:200 \
        --json /tmp/regions.json
    # family caches
    python benchmarks/calibrate_regions.py --suite-dirs /tmp/suite_2027:200 /tmp/suite_2028:200
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from rich.progress import track

from mission.localize.api import localize_log
from mission.threads import limit_worker
from mission.workshop.suite import unseen_flight
from mission.workshop.suite_cache import read_suite

LEVELS = (0.5, 0.9)


def truth_level(job: tuple[int | str, int, str]) -> float:
    """The truth's HPD level under the default selfcal posterior on benchmark flight ``i`` of
    ``seed`` (or of the benchmark cache folder ``seed`` names)."""
    seed, i, family = job
    log, truth, _ = (
        read_suite(seed).load(i) if isinstance(seed, str) else unseen_flight(seed, i, family)
    )
    est = localize_log(log, method="selfcal")
    return est.posterior.hpd_level(float(truth[0]), float(truth[1]))


def masses(q: np.ndarray) -> dict[float, float]:
    """Nominal level -> the HPD mass that covers the truths ``q`` at that rate (their
    percentile)."""
    return {lev: float(np.percentile(q, 100 * lev)) for lev in LEVELS}


def coverage(q: np.ndarray, m: dict[float, float]) -> dict[float, float]:
    """Nominal level -> share (%) of truths inside the set of mass ``m[level]``."""
    return {lev: float(100 * np.mean(q < m[lev])) for lev in LEVELS}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--seeds", nargs="+", default=["2026:200", "2027:100", "2028:200"], help="SEED:N ..."
    )
    ap.add_argument("--family", default="afar")
    ap.add_argument(
        "--suite-dirs",
        nargs="+",
        help="benchmark caches instead of --seeds (DIR:N ...; e.g. "
        "rfsl dataset --suite unseen --logs --family mission/data/afar_family.json)",
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", help="write masses, coverages and every flight's level here")
    args = ap.parse_args()
    seeds = (
        [(d.rsplit(":", 1)[0], int(d.rsplit(":", 1)[1])) for d in args.suite_dirs]
        if args.suite_dirs
        else [tuple(int(v) for v in s.split(":")) for s in args.seeds]
    )
    jobs = [(seed, i, args.family) for seed, n in seeds for i in range(n)]
    with ProcessPoolExecutor(args.workers, initializer=limit_worker) as ex:
        q_all = np.array(
            list(
                track(
                    ex.map(truth_level, jobs, chunksize=4),
                    total=len(jobs),
                    description="truth HPD levels",
                )
            )
        )
    by_seed = {seed: q_all[[j[0] == seed for j in jobs]] for seed, _ in seeds}
    m = masses(q_all)
    out = {
        "family": args.family,
        "seeds": dict(seeds),
        "masses": m,
        "coverage_in_sample": {},
        "coverage_leave_one_seed_out": {},
        "levels": {str(s): q.tolist() for s, q in by_seed.items()},
    }
    print(
        f"masses from {q_all.size} flights: "
        + ", ".join(f"{lev:g} -> {v:.3f}" for lev, v in m.items())
    )
    for seed, q in by_seed.items():
        rest = (
            np.concatenate([v for s, v in by_seed.items() if s != seed]) if len(by_seed) > 1 else q
        )
        out["coverage_in_sample"][seed] = cin = coverage(q, m)
        out["coverage_leave_one_seed_out"][seed] = cout = coverage(q, masses(rest))
        print(
            f"seed {seed} ({q.size}): in-sample {cin[0.5]:.1f} / {cin[0.9]:.1f} %, "
            f"held out {cout[0.5]:.1f} / {cout[0.9]:.1f} %"
        )
    folds = np.array_split(np.random.default_rng(0).permutation(q_all.size), 5)
    hits = {lev: 0 for lev in LEVELS}
    for f in folds:
        mk = masses(np.delete(q_all, f))
        for lev in LEVELS:
            hits[lev] += int(np.sum(q_all[f] < mk[lev]))
    out["coverage_5fold"] = cv = {lev: 100.0 * hits[lev] / q_all.size for lev in LEVELS}
    print(f"5-fold cross-validated coverage: {cv[0.5]:.1f} / {cv[0.9]:.1f} %")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
