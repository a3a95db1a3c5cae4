"""Benchmark: dataset generation speed in flights per second (simulation + both feature kinds).

python benchmarks/bench_dataset.py [--n 60] [--workers 1 2] [--randomise]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    from mission.localize.dataset import DatasetConfig, Randomisation, generate_dataset

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument(
        "--randomise", action="store_true", help="the recommended randomisation (shorter flights)"
    )
    args = ap.parse_args()
    r = Randomisation()
    if args.randomise:
        r = Randomisation(
            altitude_m=(20, 47),
            trajectories=("spiral", "lawnmower", "edge_sweep", "expanding_square", "random_waypoints"),
            random_params=True,
            truncate=(0.5, 1.0),
            patterns=("dipole", "measured"),
            random_heading=True,
        )
    for w in args.workers:
        cfg = DatasetConfig(
            str(REPO / "missions" / "spiral.yaml"), args.n, seed=0, chunk=500, randomisation=r
        )
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            generate_dataset(cfg, d, workers=w)
            dt = time.perf_counter() - t
        print(
            f"{args.n} flights ({'randomised' if args.randomise else 'spiral 30 m'}, e2r, both feature kinds), "
            f"{w} worker(s): {dt:.1f} s = {args.n / dt:.1f} flights/s"
        )


if __name__ == "__main__":
    main()
