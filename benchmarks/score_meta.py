"""Which candidate is right, learned from family draws: a model of each candidate's error from what
the flight shows, scored against today's default by a rule written before scoring (issue 32).

Why: on every real flight one of the candidates is close to the truth, a different one each time
(best of the candidates 22.8 m on the shared six against the default's 34.2), and no score from the
flight's RSS tells which (models/README.md, "The evidence stage"). What is left: learn, on flights
drawn from the reality-fitted family where the truth is known, how a candidate's error follows what
is visible without the truth (its kind, its domain flag, its posterior mode's mass, its held-out
evidence, how far it lies from the others and from the default, how far outside the flown area),
and answer with the candidate predicted closest.

Rule (written 2026-11-28 06:10 UTC, before any flight was scored with this model):
1. The model, fixed here: ridge regression (alpha 1) of log(1 + the candidate's error in m) on the
   standardised features of ``features`` below; one row per candidate. The flight's answer is the
   candidate with the lowest prediction. Nothing else is tried or tuned.
2. Benchmark: the 200 flights of the seed-2026 cache of ``mission/data/afar_family.json`` (the
   evidence stage's candidate cache, ``score_evidence.py collect``), cross-fitted: five folds by
   flight index mod 5, each flight answered by the model fitted on the other four folds.
3. Real: the six shared flights, answered by the model fitted on all 200 benchmark flights (no real
   flight is ever fitted on; the grid candidate's preset is the other team's, as cached).
4. Decision: ``mission.workshop.decision.pooled_decision`` against today's default (``fusion``), the
   issue-24 rule (relative paired difference, real resampled by team, benchmark by flight; adopted
   when the pooled 90 % interval lies below zero and neither source's lies above zero). Adopted: the
   evidence stage answers with it and becomes the real-log default (regions to be calibrated then).
   Not adopted: the figures are reported and the model is not shipped.
Also printed, deciding nothing: the evidence stage's median of candidates on the same flights, how
often the chosen candidate is the best one, and the headroom recovered.

    python benchmarks/score_meta.py --json /tmp/evidence_cache.jsonl
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from score_evidence import (  # this folder: run as a script
    err_m,
    print_decision,
    print_errors,
    read_cache,
)
from sklearn.linear_model import Ridge
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from mission.localize.stacking import geometric_median
from mission.spec import load_mission

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("selfcal", "selfcal mode", "grid", "rfsl_spiral_e2r", "rfsl_spiral_e2r_ens5", "fusion")
FOLDS = 5


def kind(source: str) -> str:
    """The candidate's kind from its cached source name."""
    if source.startswith("selfcal mode"):
        return "selfcal mode"
    if source.startswith("grid"):
        return "grid"
    return source


def features(r: dict, area) -> np.ndarray:
    """(K, F) features of flight ``r``'s K candidates, none of which uses the truth: kind (one-hot),
    in-domain flag, posterior mode mass, held-out evidence relative to the flight's best (nats),
    distance to the candidates' geometric median and to the default (100 m), share of the other
    candidates within 30 m, distance outside the flight area (100 m), the flight's candidate spread
    (100 m)."""
    xy = np.array([[c["x_m"], c["y_m"]] for c in r["cands"]])
    k = len(xy)
    one_hot = np.array([[kind(c["source"]) == n for n in KINDS] for c in r["cands"]], float)
    dom = np.array([float(c.get("in_domain", True)) for c in r["cands"]])
    mass = np.array([float(c.get("mode_mass", 0.0)) for c in r["cands"]])
    e = np.asarray(r["block_lpd"], float).sum(axis=1)
    ev = e - e.max()
    med = geometric_median(xy)
    d_med = np.hypot(*(xy - med).T) / 100.0
    d_def = np.hypot(*(xy - np.asarray(r["default"])).T) / 100.0
    pair = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    near = ((pair <= 30.0).sum(axis=1) - 1) / max(k - 1, 1)
    outside = np.maximum(-area.signed_distance(xy), 0.0) / 100.0
    spread = np.full(k, np.median(d_med))
    return np.column_stack([one_hot, dom, mass, ev, d_med, d_def, near, outside, spread])


def _targets(r: dict) -> np.ndarray:
    return np.log1p([err_m([c["x_m"], c["y_m"]], r) for c in r["cands"]])


def _model():
    return make_pipeline(StandardScaler(), Ridge(alpha=1.0))


def _fit(rows: list[dict], area):
    X = np.vstack([features(r, area) for r in rows])
    y = np.concatenate([_targets(r) for r in rows])
    return _model().fit(X, y)


def _answer(model, r: dict, area) -> tuple[np.ndarray, int]:
    k = int(np.argmin(model.predict(features(r, area))))
    c = r["cands"][k]
    return np.array([c["x_m"], c["y_m"]]), k


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--json", required=True, help="the evidence stage's candidate cache")
    args = p.parse_args()
    real, bench = read_cache(args.json)
    area = load_mission(ROOT / "missions" / "spiral.yaml").field.flight_area
    idx = np.array([int(r["name"].split()[1]) for r in bench])
    ans: dict[str, list] = {"bench": [None] * len(bench), "real": []}
    for f in range(FOLDS):
        model = _fit([r for r, i in zip(bench, idx, strict=True) if i % FOLDS != f], area)
        for j in np.flatnonzero(idx % FOLDS == f):
            ans["bench"][j] = _answer(model, bench[j], area)
    full = _fit(bench, area)
    ans["real"] = [_answer(full, r, area) for r in real]
    coef = full[-1].coef_
    names = [*KINDS, "in domain", "mode mass", "evidence", "d median", "d default", "near",
             "outside", "spread"]  # fmt: skip
    print("model fitted on all 200 (standardised coefficients, log(1 + error)):")
    print("  " + ", ".join(f"{n} {c:+.2f}" for n, c in zip(names, coef, strict=True)))
    out = {}
    for src, rs in (("real", real), ("bench", bench)):
        out[src] = {
            "default": [err_m(r["default"], r) for r in rs],
            "meta": [err_m(a[0], r) for a, r in zip(ans[src], rs, strict=True)],
            "median of candidates": [
                err_m(geometric_median(np.array([[c["x_m"], c["y_m"]] for c in r["cands"]])), r)
                for r in rs
            ],
            "best candidate": [min(err_m([c["x_m"], c["y_m"]], r) for c in r["cands"]) for r in rs],
        }
        print_errors(src, out[src], rs)
        best = np.mean(
            [np.isclose(out[src]["meta"][i], out[src]["best candidate"][i]) for i in range(len(rs))]
        )
        print(f"      the chosen candidate is the best one on {100 * best:.0f} % of flights")
        if src == "real":
            for r, a, (pt, k) in zip(rs, out[src]["default"], ans[src], strict=True):
                print(
                    f"    {r['name']:16s} default {a:6.1f}  meta {err_m(pt, r):6.1f} "
                    f"({r['cands'][k]['source']})"
                )
    print_decision(out, real, "meta")


if __name__ == "__main__":
    main()
