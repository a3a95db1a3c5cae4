"""Flights surveyed at two altitudes: what the cruise selection keeps, and the self-calibrating
error.

Why: the unseen-flight benchmark flies one altitude per flight, but other teams fly at 20-47 m, and
a flight split between two survey altitudes defeated the single-band rule (its band sat at the
median height, between the levels), and a cell flown at both altitudes must not be averaged into one
point between them. Each flight: a lawnmower over the AFAR overlap flown at A ~ U(15, 30) m and at B
~ U(35, 60) m (``two_level_path``: ``split`` or ``repeat``), take-off from and landing at the
ground, the `afar` preset's physics, shadowing 6 dB over 30 m, 2 dB noise, transmitter uniform in
the overlap.  Rules compared: the levels rule (``cruise_mask``, now) with cells per level (now) or
merged, one level only (``max_altitudes=1``), and the single band about the upper part's median (the
rule before levels; written out here: it no longer exists in the package).

    python experiments/cruise_levels.py --n 40 --seed 7      # 48 s, 1 core
"""

from __future__ import annotations

import argparse

import numpy as np

from mission.errors import InputError
from mission.geo import afar_field
from mission.localize.preprocess import cruise_mask
from mission.localize.selfcal import SelfCalibratingGrid
from mission.physics.presets import preset_model
from mission.simulate import SimConfig, simulate_flight
from mission.trajectory.generators import lawnmower, overlap_area


def two_level_path(fld, rng: np.random.Generator, scenario: str) -> np.ndarray:
    """Ground -> legs at A -> legs at B -> ground (waypoints ENU, m). ``split``: the first share of
    the lawnmower's legs at A, the rest at B (each level covers part of the area); ``repeat``: the
    whole lawnmower at A, then back along it at B (both levels over the same cells)."""
    a, b = rng.uniform(15.0, 30.0), rng.uniform(35.0, 60.0)
    wp = lawnmower(
        fld, 1.0, spacing_m=rng.uniform(18.0, 30.0), direction=str(rng.choice(["ew", "ns"]))
    )
    if scenario == "repeat":
        wp = np.vstack([wp, wp[::-1]])
        k = len(wp) // 2
    else:
        k = int(np.clip(round(rng.uniform(0.3, 0.7) * len(wp)), 2, len(wp) - 2))
    wp[:k, 2], wp[k:, 2] = a, b
    start, end = wp[0].copy(), wp[-1].copy()
    start[2] = end[2] = 0.0
    return np.vstack([start, wp, end])


def single_band_before(h: np.ndarray) -> np.ndarray:
    """The rule before levels: the band max(3 m, 15 %) about the median of the samples above half
    the 99th pct."""
    hc = float(np.median(h[h >= 0.5 * np.percentile(h, 99)]))
    return np.abs(h - hc) <= max(3.0, 0.15 * hc)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    fld = afar_field()
    model = preset_model("afar")
    per_level = SelfCalibratingGrid(area=fld.rover_area)
    merged = SelfCalibratingGrid(area=fld.rover_area, altitude_gap_m=np.inf)
    cfg = SimConfig(
        noise_db=2.0,
        shadowing_db=6.0,
        shadowing_corr_m=30.0,
        attitude_perturbation_deg=2.0,
        perturbation_corr_s=0.3,
    )
    rules = {
        "levels, cells per level (now)": (lambda h: cruise_mask(h).mask, per_level),
        "levels, cells merged": (lambda h: cruise_mask(h).mask, merged),
        "one level": (lambda h: cruise_mask(h, max_altitudes=1).mask, per_level),
        "single band (before)": (single_band_before, merged),
    }
    for scenario in ("split", "repeat"):
        kept: dict[str, list[float]] = {r: [] for r in rules}
        err: dict[str, list[float]] = {r: [] for r in rules}
        for i in range(args.n):
            rng = np.random.default_rng(np.random.SeedSequence([args.seed, i]))
            tx = np.r_[overlap_area(fld).sample_uniform(1, rng)[0], 1.5]
            f = simulate_flight(two_level_path(fld, rng, scenario), tx, model, cfg, rng)
            for r, (rule, loc) in rules.items():
                m = rule(f.enu_m[:, 2])
                kept[r].append(float(m.mean()))
                try:
                    e = loc.predict(f.select(m))
                except InputError:  # too few cells left to localize: counted apart
                    err[r].append(np.nan)
                    continue
                err[r].append(float(np.hypot(e.x_m - tx[0], e.y_m - tx[1])))
        print(
            f"{args.n} two-level flights, scenario {scenario} (seed {args.seed}); selfcal on "
            "the kept samples"
        )
        for r in rules:
            e = np.asarray(err[r])
            ok = np.isfinite(e)
            print(
                f"  {r:30s} kept {100 * np.mean(kept[r]):5.1f} % (min "
                f"{100 * np.min(kept[r]):4.1f} %), localized "
                f"{ok.sum()}/{e.size}, error mean {np.nanmean(e):5.1f} m, median "
                f"{np.nanmedian(e):5.1f} m"
            )


if __name__ == "__main__":
    main()
