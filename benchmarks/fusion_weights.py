"""Should the real-log fusion weight its members by their own uncertainty instead of a plain mean?

Candidate: the self-calibrating point ``a`` and the network point ``b`` weighted by the inverse
square of each member's 50 % region scale: ``sqrt(area / pi)`` of the self-calibrating posterior's
50 % HPD set (per flight) and the network's 50 % error-circle radius for real logs (its card's
``real`` calibration); the plain mean is the incumbent (``api.fusion``).  One ``localize --method
fusion`` run per flight gives both points, the posterior's regions and the truth, so both fusions
are scored on identical members.

Rule, written before scoring (this docstring was committed before any figure was computed): adopt
the weighted mean unless it is worse beyond the interval on either source, i.e. unless the 90 %
paired bootstrap interval of (weighted - plain) mean error lies entirely above zero (a) on the six
real AFAR flights, resampled over teams (nothing is fitted on real flights: the weights come from
the benchmark calibrations, so every real flight is held out), or (b) on the reality-fitted
benchmark cache (``--suite-dir``), resampled over flights.

    rfsl dataset --suite unseen --logs --family mission/data/afar_family.json --n 200 \
        --out /tmp/suite_fit
    python benchmarks/fusion_weights.py --suite-dir /tmp/suite_fit --mat ../shared/data/afar2023/mat
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from _scoring import flight_with_truth, real_logs_and_pool, scoring_parser

from mission.evidence import mean_interval, paired_difference
from mission.gap.familyfit import team_of
from mission.localize.api import fusion_model_path, localize_log
from mission.localize.error_circles import card_calibration


def region_scale_m(est, level: float = 0.5) -> float | None:
    """The radius of the disc with the area of an estimate's ``level`` region, ``sqrt(area / pi)``
    (for an error circle its radius), or None when it has no such region: the member's own
    uncertainty in metres."""
    reg = est.region(level)
    if reg is None:
        return None
    return float(reg.radius_m) if reg.is_circle else float(np.sqrt(reg.area_m2 / np.pi))


def inverse_square_weight(scale_a: float, scale_b: float) -> float:
    """Weight of member a in a two-member fusion weighted by the inverse square of each member's
    region scale (inverse variance for isotropic errors): ``b^2 / (a^2 + b^2)``; a member with the
    tighter region counts more."""
    a2, b2 = float(scale_a) ** 2, float(scale_b) ** 2
    return b2 / (a2 + b2)


def one(job: tuple[str, str, int]) -> dict:
    """Both members' points, their 50 % scales and the truth on one flight (log ENU m)."""
    kind, src, i = job
    log, truth = flight_with_truth(kind, src, i)
    est = localize_log(log, method="fusion")
    comp = est.extras["components"]
    return {
        "truth": np.asarray(truth, dtype=float),
        "a": np.asarray(comp["selfcal"]),
        "b": np.asarray(comp[Path(fusion_model_path()).name]),
        "ra": region_scale_m(est),
    }


def network_radius() -> float:
    """The fusion network's 50 % error-circle radius for real logs (its card's ``real``
    calibration)."""
    rec, why = card_calibration(fusion_model_path(), "real")
    if rec is None:
        raise SystemExit(why)
    return float(rec["radii_m"][0.5])


def errors(rows: list[dict], rb: float) -> tuple[np.ndarray, np.ndarray]:
    """(plain-mean errors, weighted-mean errors) in metres; ``rb`` the network's 50 % radius."""

    plain, weighted = [], []
    for r in rows:
        w = inverse_square_weight(r["ra"], rb)
        plain.append(np.hypot(*(0.5 * (r["a"] + r["b"]) - r["truth"])))
        weighted.append(np.hypot(*(w * r["a"] + (1.0 - w) * r["b"] - r["truth"])))
    return np.array(plain), np.array(weighted)


def main() -> None:
    args = scoring_parser(__doc__).parse_args()
    with real_logs_and_pool(args) as (real, ex):
        rows_r = list(ex.map(one, [("real", str(p), 0) for p in real]))
        rows_b = list(
            ex.map(one, [("suite", args.suite_dir, i) for i in range(args.n)], chunksize=4)
        )
    teams = [team_of(Path(p).stem) for p in real]
    rb = network_radius()
    print(f"network 50 % radius (card, real): {rb:.1f} m")
    verdict = []
    for label, rows, groups in (
        ("six real flights (teams)", rows_r, teams),
        (f"benchmark {Path(args.suite_dir).name} (flights)", rows_b, None),
    ):
        p, w = errors(rows, rb)
        d = paired_difference(w, p, groups)
        print(
            f"{label}, n={len(p)}: plain {mean_interval(p, groups).fmt()} m, weighted "
            f"{mean_interval(w, groups).fmt()} m, weighted - plain {d.fmt()} m; selfcal weight "
            "median "
            f"{np.median([rb**2 / (r['ra'] ** 2 + rb**2) for r in rows]):.2f}"
        )
        verdict.append(d.lo > 0)
    print(
        "rule: "
        + (
            "keep the plain mean (the weighted mean is worse beyond the interval)"
            if any(verdict)
            else "adopt the weighted mean (not worse beyond the interval on either source)"
        )
    )
    # Scored 2026-11-25 on the reality-fitted family's cache seed 2026 (200 flights) with
    # rfsl_spiral_e2r's real 50 % radius 76.2 m.  With the afar-family selfcal masses (0.511 /
    # 0.954): real 34.2 -> 34.6 m, paired +0.3 [-1.2, +1.9] m over teams; benchmark 74.0 -> 72.5 m,
    # -1.5 [-2.6, -0.4] m: adopt.  With the masses recalibrated on the reality-fitted family (0.339
    # / 0.870, the shipped ones; selfcal weight median 0.70): real 34.2 -> 36.9 m, +2.7 [+2.1, +3.3]
    # m over teams (two teams: a narrow interval); benchmark 74.0 -> 72.5 m, -1.5 [-3.0, 0.0] m:
    # worse beyond the interval on the real flights, so the plain mean stays.


if __name__ == "__main__":
    main()
