"""Benchmark: dataset generation speed in flights per second (simulation + features).

python benchmarks/bench_dataset.py [--n 60] [--workers 1 2] [--randomise | --suite] \
    [--features clustering]

Prints wall-clock flights/s and CPU milliseconds per flight (this process and its workers): on a
shared, busy machine the CPU figure is the robust one (flights/s on k idle cores ~= k * 1000 /
cpu_ms); the load average at the end of each run is printed with it.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from mission.workshop.dataset import DatasetConfig, Randomisation, generate_dataset

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument(
        "--randomise", action="store_true", help="the recommended randomisation (shorter flights)"
    )
    ap.add_argument(
        "--suite", action="store_true", help="flights of the unseen-flight benchmark family"
    )
    ap.add_argument(
        "--features", default="clustering,normalised_rss", help="stored inputs (default both)"
    )
    args = ap.parse_args()
    r = Randomisation()
    if args.randomise:
        r = Randomisation(
            altitude_m=(20, 47),
            trajectories=(
                "spiral",
                "lawnmower",
                "edge_sweep",
                "expanding_square",
                "random_waypoints",
            ),
            random_params=True,
            truncate=(0.5, 1.0),
            patterns=("dipole", "measured"),
            random_heading=True,
        )
    feats = tuple(f.strip() for f in args.features.split(",") if f.strip())
    what = (
        "unseen-suite family"
        if args.suite
        else "randomised e2r"
        if args.randomise
        else "spiral 30 m e2r"
    )
    for w in args.workers:
        if args.suite:
            cfg = DatasetConfig(None, args.n, seed=1, chunk=500, features=feats, suite="unseen")
        else:
            cfg = DatasetConfig(
                str(REPO / "missions" / "spiral.yaml"),
                args.n,
                seed=0,
                chunk=500,
                randomisation=r,
                features=feats,
            )
        with tempfile.TemporaryDirectory() as d:
            c0 = os.times()
            t = time.perf_counter()
            generate_dataset(cfg, d, workers=w)
            dt = time.perf_counter() - t
            c1 = os.times()
        cpu = sum(c1[:4]) - sum(c0[:4])  # user + system of this process and its (joined) workers
        print(
            f"{args.n} flights ({what}, {'+'.join(feats)}), {w} worker(s): {dt:.1f} s = "
            f"{args.n / dt:.1f} "
            f"flights/s; CPU {1000 * cpu / args.n:.1f} ms/flight; load average "
            + " ".join(f"{v:.2f}" for v in os.getloadavg())
            + f" on {os.cpu_count()} cores"
        )


if __name__ == "__main__":
    main()
