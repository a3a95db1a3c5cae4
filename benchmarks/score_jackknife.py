"""Per-flight weights for the default's members from a block jackknife, by a rule written before
scoring (issue 32: let each flight's own data say which answer it supports).

Why: on each flight a different member of the default is close to the truth.  A member whose answer
moves a lot when a part of the track is left out is one the flight does not pin down; the
delete-one-block jackknife (Quenouille, Tukey; contiguous blocks for dependent data, Kunsch 1989)
measures that per flight and per member without a physics model, for the networks as for the
searches, where the held-out RSS evidence (``score_evidence.py``) favoured the member fitted under
its own nuisance model.

Rule (written 2026-11-28 14:55 UTC, before any jackknife was computed on any flight):
1. Members: selfcal, the ``afar`` grid (on a real flight the preset fitted without its team) and
   ``rfsl_spiral_e2r``.  Each runs on the flight's selected samples with one of ``K`` = 10
   consecutive blocks of equal sample count left out, ``K`` times; its jackknife variance is
   ``V = (K - 1) / K * sum_k |p_k - mean(p)|^2`` (m^2), ``p_k`` its point without block k.
2. Schemes, each from the members' points on all samples: (J1) the fusion's two members (selfcal,
   ``rfsl_spiral_e2r``) weighted by ``1 / (V + V0)``; (J2) the three members weighted so; (J3) the
   member of the three with the smallest ``V``.  ``V0`` = 25 m^2 (5 m: a member that never moves
   does not take every weight).
3. The scheme with the lowest mean error on the benchmark's development split (flights 0-59) is
   chosen; it is scored further only if that mean is below the default's on the same flights.
4. Scored once against today's default (the fusion) on benchmark flights 60-199 and the six real
   flights held out by team, with the issue-24 rule (``workshop.decision.pooled_decision``):
   adopted as the default's point when the pooled 90 % interval lies below zero and neither
   source's lies above zero.  Not adopted: reported, nothing changes.
Reported beside: each member's Spearman correlation between ``sqrt(V)`` and its error over the
benchmark flights (does the jackknife see the error at all?).

    python benchmarks/score_jackknife.py collect --suite-dir /tmp/suite_fam \\
        --mat ../shared/data/afar2023/mat --json /tmp/jackknife.jsonl --workers 2
    python benchmarks/score_jackknife.py score --json /tmp/jackknife.jsonl
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.stats import spearmanr
from score_evidence import (  # this folder: run as a script
    choose_on_dev,
    collect_parser,
    collect_rows,
    err_m,
    read_cache,
    score_held_out,
    split_dev,
)
from threadpoolctl import threadpool_limits

from mission.flightlog import read_flight_log
from mission.localize.api import DEFAULT_PHYSICS_PRESET, localize_log, run_member, search_area
from mission.localize.preprocess import select_samples
from mission.shipped import shipped_model

K = 10
V0_M2 = 25.0
MEMBERS = ("selfcal", "grid", "rfsl_spiral_e2r")
FUSION_MEMBERS = ("selfcal", "rfsl_spiral_e2r")


def _member(name: str, part, log, preset: str) -> tuple[float, float]:
    """One member's point on ``part`` (the log's frame)."""
    area = search_area(log)
    if name == "selfcal":
        _, e = run_member("selfcal", part, log.origin, area=area)
    elif name == "grid":
        _, e = run_member("grid", part, log.origin, area=area, physics_preset=preset)
    else:
        _, e = run_member("onnx", part, log.origin, model_path=shipped_model(f"{name}.onnx"))
    return float(e.x_m), float(e.y_m)


def jackknife(points: np.ndarray) -> float:
    """The delete-one-block jackknife variance (m^2) of ``points`` (K, 2), one per left-out
    block."""
    k = len(points)
    return float((k - 1) / k * np.sum((points - points.mean(axis=0)) ** 2))


def _one(job: tuple[str, str, str | None, list | None]) -> dict:
    path, name, preset, truth = job
    with threadpool_limits(1):
        log = read_flight_log(path)
        part, _ = select_samples(log)
        preset = preset or DEFAULT_PHYSICS_PRESET
        default = localize_log(log)
        n = len(part)
        block = np.minimum((np.arange(n) * K) // n, K - 1)
        out = {}
        for m in MEMBERS:
            full = _member(m, part, log, preset)
            reps = np.array([_member(m, part.select(block != k), log, preset) for k in range(K)])
            out[m] = {"point": list(full), "var_m2": jackknife(reps)}
    t = log.truth_enu if truth is None else truth
    return {
        "name": name,
        "truth": [float(t[0]), float(t[1])],
        "default": [default.x_m, default.y_m],
        "members": out,
        "cands": [],
    }


def collect(args) -> None:
    collect_rows(args, _one, "jackknife")


def _weighted(r: dict, names: tuple[str, ...]) -> np.ndarray:
    p = np.array([r["members"][m]["point"] for m in names])
    w = 1.0 / (np.array([r["members"][m]["var_m2"] for m in names]) + V0_M2)
    return (w[:, None] * p).sum(axis=0) / w.sum()


def _steadiest(r: dict) -> np.ndarray:
    m = min(MEMBERS, key=lambda k: r["members"][k]["var_m2"])
    return np.asarray(r["members"][m]["point"])


SCHEMES = {
    "J1: fusion's two by 1/(V+V0)": lambda r: _weighted(r, FUSION_MEMBERS),
    "J2: the three by 1/(V+V0)": lambda r: _weighted(r, MEMBERS),
    "J3: the steadiest of the three": _steadiest,
}


def score(args) -> None:
    real, bench = read_cache(args.json)
    dev, fresh = split_dev(bench)
    for m in MEMBERS:
        sd = [np.sqrt(r["members"][m]["var_m2"]) for r in bench]
        er = [err_m(r["members"][m]["point"], r) for r in bench]
        rho = spearmanr(sd, er).statistic
        print(
            f"{m:16s} benchmark: mean error {np.mean(er):5.1f} m, median jackknife sd "
            f"{np.median(sd):5.1f} m, Spearman(sd, error) {rho:+.2f}"
        )
    for r in real:
        sds = "  ".join(f"{m} {np.sqrt(r['members'][m]['var_m2']):5.1f}" for m in MEMBERS)
        print(f"  {r['name']:16s} jackknife sd (m): {sds}")
    best = choose_on_dev(dev, SCHEMES)
    if best is not None:
        score_held_out(
            real,
            fresh,
            "jackknife",
            SCHEMES[best],
            lambda r: min(err_m(r["members"][m]["point"], r) for m in MEMBERS),
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    collect_parser(sub)
    s = sub.add_parser("score")
    s.add_argument("--json", required=True)
    a = p.parse_args()
    {"collect": collect, "score": score}[a.cmd](a)


if __name__ == "__main__":
    main()
