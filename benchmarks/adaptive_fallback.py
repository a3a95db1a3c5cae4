"""The fallback to the fixed spiral, as a counterfactual on ``bench_adaptive.py --json`` rows: a
flight whose first round was flown more than ``--radius`` metres from its target (moved inside the
fence) takes the fixed arm's error, every other flight keeps the adaptive answer's.

    python benchmarks/bench_adaptive.py --flights 40 --jobs 2 --seed 2038 --family mission --json M
    python benchmarks/adaptive_fallback.py M [A ...]

The rule and the figures: docs/adaptive.md, "Finish the spiral when no round can reach the
estimate".  With ``--decide`` and two outputs (the mission's physics first, the ``afar`` family
second) the confirmatory rule is applied: ``mission.workshop.decision.pooled_decision`` with today's
adaptive answer as the incumbent, each setting half of the pooled relative difference.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mission.evidence import mean_interval, paired_difference
from mission.workshop.decision import pooled_decision


def falls_back(row: dict, radius_m: float) -> bool:
    """Whether the flight's first round flew its square more than ``radius_m`` from its target."""
    planned = row["adaptive"].get("planned") or []
    if not planned:
        return False
    target, centre = (np.asarray(v, dtype=float) for v in planned[0])
    return float(np.hypot(*(target - centre))) > radius_m


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("json", nargs="+", help="bench_adaptive.py --json outputs")
    p.add_argument("--radius", type=float, default=20.0, help="the rounds' half side (m)")
    p.add_argument("--decide", action="store_true", help="apply the rule to MISSION AFAR")
    args = p.parse_args()
    errors = []
    for path in args.json:
        rows = [
            r
            for r in json.loads(Path(path).read_text())
            if r["fixed"]["error_m"] is not None and r["adaptive"]["error_m"] is not None
        ]
        fx = np.array([r["fixed"]["error_m"] for r in rows])
        ad = np.array([r["adaptive"]["error_m"] for r in rows])
        back = np.array([falls_back(r, args.radius) for r in rows])
        fb = np.where(back, fx, ad)
        errors.append({"adaptive": ad, "fallback": fb})
        print(f"{path}: {len(rows)} flights, {back.sum()} fall back")
        for name, v in (("fixed", fx), ("adaptive", ad), ("with the fallback", fb)):
            print(f"  {name:18s} {mean_interval(v, seed=1).fmt()} m")
        print(f"  fallback - adaptive {paired_difference(fb, ad, seed=1).fmt()} m")
        print(f"  fallback - fixed    {paired_difference(fb, fx, seed=1).fmt()} m")
        if back.any():
            print(
                f"  on the flights that fall back: fixed {fx[back].mean():.1f} m, adaptive "
                f"{ad[back].mean():.1f} m"
            )
    if args.decide:
        if len(errors) != 2:
            p.error("--decide needs two outputs: the mission's physics, then the afar family")
        dec = pooled_decision(errors[0], None, errors[1], "adaptive", seed=3)
        m = dec["methods"]["fallback"]
        print(
            f"relative paired difference, fallback - adaptive: mission {m['real'].fmt(3)}, afar "
            f"{m['bench'].fmt(3)}, pooled {m['pooled'].fmt(3)}"
        )
        print(f"decision: {'build the fallback' if dec['changed'] else 'do not build it'}")


if __name__ == "__main__":
    main()
