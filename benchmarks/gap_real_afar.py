"""Reproduce the real-flight gap figures: the six AFAR 2023 flights (teams 288, 328; rover locations 1-3).

Usage::

    python benchmarks/gap_real_afar.py [--out gap_real] [--fit-max 1500] [--quick]

What it does (issue 6): imports the MAT files in memory (``mission.importers.afar``) with the rover truth of
``../shared/data/README.md``, keeps the airborne samples (height > 10 m), then

1. the gap of free-space / two-ray / e2r (paper's 22 dB comparison) per flight and pooled,
2. the greedy ladder from free space (isotropic antennas) up, pooled over the flights (blocks split) and
   with whole flights held out (``--split flights``: the MPACT-Lab hypotheses on held-out flights),
3. team 288 location 3: where the strongest RSS is and where a model-based grid search puts the rover,
4. everything written to ``OUT/`` (PNGs + JSON; ``summary.json`` holds the tables of the final report).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO / ".." / "shared"
MAT = SHARED / "data" / "afar2023" / "mat"


def load(min_height_m: float = 10.0):
    """The six flights as ``FlightSamples`` objects (airborne samples only)."""
    from mission.gap.align import afar2023_flights

    return afar2023_flights(MAT, min_height_m)


def suspect_288_loc3(flights) -> dict:
    """Where the strongest RSS of each loc-3 flight is, and where a free-space / e2r grid search puts the rover."""
    from mission.gap.diagnose import base_pipeline
    from mission.gap.pipeline import LocalizationModel
    from mission.localize.classical import ModelGridSearch
    from mission.samples import FlightSamples

    out = {}
    for f in flights:
        if not f.name.endswith("loc3"):
            continue
        k = 31
        sm = np.convolve(f.rss_dbm, np.ones(k) / k, mode="same")
        i = int(np.argmax(sm))
        row = {"strongest_rss_enu": f.enu_m[i, :2].round(1).tolist(),
               "strongest_to_label_m": float(np.hypot(*(f.enu_m[i, :2] - f.tx_enu_m[:2]))),
               "label_enu": f.tx_enu_m[:2].round(1).tolist()}
        for name, pat in (("free-space", "isotropic"), ("e2r", "dipole")):
            est = ModelGridSearch(LocalizationModel(base_pipeline(name, pat)), tx_height_m=1.5,
                                  area=(-80.0, -80.0, 380.0, 420.0), step_m=10.0, loss="soft_l1")
            e = est.predict(FlightSamples(enu_m=f.enu_m, rss_dbm=f.rss_dbm, attitude_rad=f.attitude_rad))
            row[f"grid_{name}_enu"] = [round(e.x_m, 1), round(e.y_m, 1)]
            row[f"grid_{name}_to_label_m"] = float(np.hypot(e.x_m - f.tx_enu_m[0], e.y_m - f.tx_enu_m[1]))
            row[f"grid_{name}_rms_db"] = float(e.extras.get("cost_rms_db", np.nan)) if hasattr(e, "extras") else None
        out[f.name] = row
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="gap_real")
    ap.add_argument("--fit-max", type=int, default=1500)
    ap.add_argument("--runs", default="pooled_blocks,pooled_flights,per_flight",
                    help="which analyses: pooled_blocks, pooled_flights, per_flight (comma-separated)")
    ap.add_argument("--slope", action="store_true", help="also fit a per-flight path-gain slope")
    args = ap.parse_args(argv)
    if not MAT.is_dir():
        print(f"no AFAR data at {MAT}", file=sys.stderr)
        return 2
    from rich.console import Console

    from mission.gap.candidates import select
    from mission.gap.diagnose import base_pipeline, diagnose, rung_table
    from mission.gap.fit import FitConfig
    from mission.gap.report import print_report, write_report

    c = Console(width=200)
    out = Path(args.out)
    flights = load()
    out.mkdir(parents=True, exist_ok=True)
    summary: dict = {"flights": {f.name: len(f) for f in flights}}
    t0 = time.time()
    summary["loc3"] = suspect_288_loc3(flights)
    c.print(summary["loc3"])
    good = [f for f in flights if f.name != "288-loc3"]
    base = base_pipeline("free-space", "isotropic")
    want = args.runs.split(",")
    runs = [r for r in [("pooled_blocks", good, "blocks"), ("pooled_flights", good, "flights")] if r[0] in want]
    if "per_flight" in want:
        runs += [(f.name, [f], "blocks") for f in flights]
    for label, fl, split in runs:
        cfg = FitConfig(split=split, fit_max_samples=args.fit_max, loss="soft_l1", slope=args.slope, seed=0)
        d = diagnose(fl, base, select("all"), cfg, base_label="free-space(iso)", pattern="dipole",
                     localize=label.startswith("pooled"),
                     area=(-80.0, -80.0, 380.0, 420.0))
        c.rule(f"{label} ({time.time() - t0:.0f} s)")
        print_report(d, c)
        write_report(d, out / label)
        summary[label] = {"gaps": {g.name: {"pooled": g.pooled, "per_flight": g.per_flight} for g in d.gaps},
                          "ladder": rung_table(d), "localization": d.localization}
        (out / f"summary_{args.runs.replace(',', '_')}.json").write_text(json.dumps(summary, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
