"""How the AFAR sounder loses lock: one level per flight, no hysteresis, flickering runs.

Why: stop 57 found that about a fifth of the real samples were read out of lock
(``experiments/receiver_lock.py``) and that how often depends on the level the model predicts.  A
receiver can lose lock at one level and regain it only at a higher one (hysteresis), or hold it for
a while after the signal fades; either would make the out-of-lock rows a state of the receiver
rather than a property of the signal where they were read.  This script asks, per flight, on the
cruise samples ``localize`` uses, in row order:
1. the power of the locked reading next to each change of state, split into losses and regains, and
   the difference of their medians with a 90 % bootstrap interval over the changes (hysteresis
   would put the regains higher);
2. how long the out-of-lock runs last (rows; about 10 per second);
3. what the sounder reads out of lock against the flight's floor (``schema.lock_floor_db``, what
   ``localize`` reports).

    python experiments/lock_mechanism.py --mat ../shared/data/afar2023/mat          # ~15 s
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from experiments.receiver_lock import quality_log
from mission.evidence import LEVEL, Interval
from mission.flightlog.schema import (
    QUALITY_COLUMN,
    SOUNDER_LOCK_DB,
    lock_edges,
    lock_floor_db,
    out_of_lock,
)
from mission.localize.preprocess import select_samples


def run_lengths(locked: np.ndarray) -> np.ndarray:
    """The lengths (rows) of the out-of-lock runs."""
    edges = np.flatnonzero(np.diff(np.r_[0, (~locked).astype(int), 0]))
    return edges[1::2] - edges[::2]


def median_gap(
    a: np.ndarray, b: np.ndarray, seed: int = 0, n_boot: int = 2000, level: float = LEVEL
) -> Interval:
    """median(b) - median(a) with a percentile bootstrap interval (each side resampled)."""
    rng = np.random.default_rng(seed)
    reps = np.median(rng.choice(b, (n_boot, len(b))), axis=1) - np.median(
        rng.choice(a, (n_boot, len(a))), axis=1
    )
    lo, hi = np.percentile(reps, [50 * (1 - level), 50 * (1 + level)])
    return Interval(float(np.median(b) - np.median(a)), float(lo), float(hi), level)


def flight_row(log) -> dict:
    """The figures of one flight (module docstring)."""
    part, _ = select_samples(log)
    p = np.asarray(part["rss_dbm"], dtype=float)
    locked = ~out_of_lock(part[QUALITY_COLUMN])
    lose, regain = lock_edges(part[QUALITY_COLUMN])
    runs = run_lengths(locked)
    floor = lock_floor_db(p, part[QUALITY_COLUMN])
    return {
        "n": len(p),
        "unlocked": float(np.mean(~locked)),
        "changes": len(lose) + len(regain),
        "lose_db": float(np.median(p[lose])),
        "regain_db": float(np.median(p[regain])),
        "hysteresis": median_gap(p[lose], p[regain]),
        "run_median": float(np.median(runs)),
        "run_p90": float(np.percentile(runs, 90)),
        "floor_db": floor,
        "unlocked_vs_floor": float(np.median(p[~locked]) - floor),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--mat", required=True, help="folder of the AFAR 2023 .mat files")
    args = ap.parse_args()
    print(f"quality >= {SOUNDER_LOCK_DB:g} dB read as locked; cruise samples, row order")
    print("flight    unlock change   lose regain  regain-lose [90 %]  runs   floor   out")
    with tempfile.TemporaryDirectory() as tmp:
        for mat in sorted(Path(args.mat).glob("*.mat")):
            r = flight_row(quality_log(mat, Path(tmp)))
            h = r["hysteresis"]
            print(
                f"{mat.stem.replace('results_useful_ori_exp_', ''):9s} "
                f"{100 * r['unlocked']:5.1f}% {r['changes']:6d} {r['lose_db']:6.1f} "
                f"{r['regain_db']:6.1f} {h.value:+5.1f} [{h.lo:+5.1f},{h.hi:+5.1f}] "
                f"{r['run_median']:2.0f}/{r['run_p90']:<3.0f}{r['floor_db']:6.1f} "
                f"{r['unlocked_vs_floor']:+5.1f}"
            )
    print("lose/regain: median power (dB) of the locked row next to a loss / a regain;")
    print("runs: out-of-lock run length, rows, p50/p90; out: median power read out of")
    print("lock minus the floor (dB)")


if __name__ == "__main__":
    main()
