"""Cross-fitted evidence over the default's members, by a rule written before scoring (issue 32:
let each flight's own data say which answer it supports).

Why: the evidence stage (``score_evidence.py``) scores each candidate's point on held-out blocks,
but the points were fitted on every block, the held-out ones included.  Selfcal's point maximises
the same likelihood the blocks are scored under, so it led whatever its error (models/README.md,
"The evidence stage").  Stacking (Yao, Vehtari, Simpson and Gelman 2018) scores each *model* by its
leave-out predictive density: the model refitted without the held-out data.  Here each member is
run again without each fold, and the fold is scored with the point found without it: a method is
credited only for what it predicts about RSS it did not see.

Rule (written 2026-11-29 08:01 UTC, committed as 088dbda before any cross-fitted point or score
was computed on any flight):
1. Members: selfcal, the ``afar`` grid (on a real flight the preset fitted without its team),
   ``rfsl_spiral_e2r``, ``rfsl_spiral_e2r_ens5`` and the fusion (today's default: the mean of
   selfcal's and ``rfsl_spiral_e2r``'s points).
2. Folds: ``K`` = 5.  A selected sample's fold is ``(floor(x / 50) + 2 floor(y / 50)) mod 5`` in the
   log's frame: 50 m squares (longer than the real flights' shadowing correlation), no two
   neighbouring squares (diagonals included) in the same fold.  Each member runs on the samples
   outside fold k (``p_mk``); the fusion's ``p_mk`` is the mean of selfcal's and the network's.
3. Scores: the self-calibrating search's cells of all selected samples, each in the fold of its
   centre; ``stacking.blocked_scores`` with the folds as blocks (offset, slope and UAV antenna
   fitted on the other folds, tempered as ``evidence_stage.selfcal_scores``).  Member m's
   cross-fitted score on fold k is fold k's density under ``p_mk`` (variant B: every member
   refitted).  Variant A: the networks keep their full-track point (a network is not fitted to
   the RSS under this likelihood, and a track with holes leaves its training domain) while
   selfcal, the grid and the fusion's selfcal half are refitted.  ``E_m``: the sum over folds.
4. Schemes (each gives a flight's point; members' points are their full-track points):
   best-A / best-B: the member with the highest ``E_m``; fusion-3-A / fusion-3-B: the fusion
   unless another member's ``E_m`` exceeds the fusion's by more than 3 (tempered nats), then that
   member; stack-A / stack-B: stacking weights (``stacking.stacking_weights`` over the (member,
   fold) scores) on the members' full-track points, their weighted mean.
5. The scheme with the lowest mean error on the benchmark's development split (flights 0-59 of the
   seed-2026 ``afar`` family suite, as ``score_evidence.py``) is chosen; it is scored further only
   if it errs less than the default there.
6. Scored once against today's default on benchmark flights 60-199 and the six real flights held
   out by team with the issue-24 rule (``workshop.decision.pooled_decision``, as
   ``score_evidence.py``): adopted as the real-log default's point when the pooled 90 % interval
   lies below zero and neither source's lies above zero.  Not adopted: reported, nothing changes.
Reported beside: how often each member is chosen; the Spearman correlation over the benchmark
between a member's ``E_m`` deficit (to the flight's best) and its error; the headroom (the best
member of each flight).

Result (2026-11-29): chosen on the development split: fusion-3-B (66.2 m against the default's
67.0); on the held-out flights it is the default on every real flight and on all but a few
benchmark ones: real 0.0 m, benchmark -0.1 [-0.7, +0.6] m, pooled -0.0 % [-0.5, +0.4]. **Not
adopted.** Cross-fitted, the members' scores still differ by 1.1-1.3 tempered nats on a real
flight (median; 1.6-1.7 on the benchmark), and the best-scored member is the closest one on 25-28 %
of the 200 benchmark flights (chance with five members: 20 %).

    python benchmarks/score_crossfit.py collect --suite-dir /tmp/suite_fam \\
        --mat ../shared/data/afar2023/mat --json /tmp/crossfit.jsonl --workers 2
    python benchmarks/score_crossfit.py score --json /tmp/crossfit.jsonl
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
from score_jackknife import _member
from threadpoolctl import threadpool_limits

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.flightlog import read_flight_log
from mission.localize.api import DEFAULT_PHYSICS_PRESET, localize_log
from mission.localize.evidence_stage import selfcal_cells, selfcal_scores
from mission.localize.preprocess import select_samples
from mission.localize.stacking import stacking_weights

K = 5
SQUARE_M = 50.0
NETWORKS = ("rfsl_spiral_e2r", "rfsl_spiral_e2r_ens5")
MEMBERS = ("selfcal", "grid", *NETWORKS, "fusion")
LEAD_NATS = 3.0


def fold_of(xy: np.ndarray) -> np.ndarray:
    """(N,) fold 0..K-1 of horizontal positions (N, 2): 50 m squares, no two neighbours alike."""
    ij = np.floor(np.asarray(xy, float) / SQUARE_M).astype(np.int64)
    return (ij[:, 0] + 2 * ij[:, 1]) % K


def _points(part, log, preset: str) -> dict[str, tuple[float, float]]:
    """Every member's point on ``part`` (the log's frame)."""
    out = {m: _member(m, part, log, preset) for m in ("selfcal", "grid", *NETWORKS)}
    out["fusion"] = tuple(0.5 * (np.array(out["selfcal"]) + out[NETWORKS[0]]))
    return {k: (float(v[0]), float(v[1])) for k, v in out.items()}


def _one(job: tuple[str, str, str | None, list | None]) -> dict:
    path, name, preset, truth = job
    with threadpool_limits(1):
        log = read_flight_log(path)
        part, _ = select_samples(log)
        preset = preset or DEFAULT_PHYSICS_PRESET
        default = localize_log(log)
        full = _points(part, log, preset)
        fold = fold_of(part.enu()[:, :2])
        folds = [_points(part.select(fold != k), log, preset) for k in range(K)]
        cells = selfcal_cells(part, DEFAULT_TX_HEIGHT_M)
        cell_fold = fold_of(cells.enu_m[:, :2])
        # the folds a flight covers, renumbered 0..B-1 (blocked_scores' blocks)
        present, block = np.unique(cell_fold, return_inverse=True)
        # candidates: every member's full point, then for each present fold its points without
        # the fold (variant B) and variant A's fusion (selfcal refitted, the network's full point)
        xy = [full[m] for m in MEMBERS]
        for k in present:
            fa = 0.5 * (np.array(folds[k]["selfcal"]) + full[NETWORKS[0]])
            xy += [folds[k][m] for m in MEMBERS] + [tuple(fa)]
        s = selfcal_scores(cells, np.array(xy), DEFAULT_TX_HEIGHT_M, block=block.ravel())
    t = log.truth_enu if truth is None else truth
    return {
        "name": name,
        "truth": [float(t[0]), float(t[1])],
        "default": [default.x_m, default.y_m],
        "full": full,
        "folds_present": present.tolist(),
        "fold_points": [folds[k] for k in present],
        "cell_counts": np.bincount(block.ravel()).tolist(),
        # (M + B (M + 1), B): rows = the M full points, then per fold b its M refitted points
        # and variant A's fusion
        "block_lpd": s.block_lpd.tolist(),
        "tau": s.tau,
    }


def collect(args) -> None:
    collect_rows(args, _one, "cross-fit")


def fold_scores(r: dict, variant: str) -> np.ndarray:
    """(members, folds) cross-fitted held-out scores of row ``r``: fold b under the point found
    without it; in variant ``A`` the networks keep their full-track point and the fusion is
    selfcal's refitted point with the network's full one."""
    lp = np.asarray(r["block_lpd"])
    m, nb = len(MEMBERS), lp.shape[1]
    out = np.empty((m, nb))
    for b in range(nb):
        base = m + b * (m + 1)  # this fold's refitted points
        for i, name in enumerate(MEMBERS):
            if variant == "A" and name in NETWORKS:
                out[i, b] = lp[i, b]
            elif variant == "A" and name == "fusion":
                out[i, b] = lp[base + m, b]
            else:
                out[i, b] = lp[base + i, b]
    return out


def _pick(r: dict, variant: str, how: str) -> np.ndarray:
    e = fold_scores(r, variant)
    pts = np.array([r["full"][m] for m in MEMBERS])
    tot = e.sum(axis=1)
    if how == "best":
        return pts[int(np.argmax(tot))]
    if how == "fusion-3":
        i, f = int(np.argmax(tot)), MEMBERS.index("fusion")
        return pts[i] if tot[i] - tot[f] > LEAD_NATS else pts[f]
    w = stacking_weights(e)
    return (w[:, None] * pts).sum(axis=0) / w.sum()


SCHEMES = {
    f"{how}-{v}": (lambda r, v=v, how=how: _pick(r, v, how))
    for v in ("A", "B")
    for how in ("best", "fusion-3", "stack")
}


def score(args) -> None:
    real, bench = read_cache(args.json)
    dev, fresh = split_dev(bench)
    for v in ("A", "B"):
        totals = np.array([fold_scores(r, v).sum(axis=1) for r in bench])  # (flights, members)
        chosen = {m: 0 for m in MEMBERS}
        for i in np.argmax(totals, axis=1):
            chosen[MEMBERS[int(i)]] += 1
        print(f"variant {v}: the best-scored member on the benchmark's {len(bench)} flights:")
        print("  " + ", ".join(f"{m} {n}" for m, n in chosen.items()))
        deficits = totals.max(axis=1, keepdims=True) - totals
        for m_i, m in enumerate(MEMBERS):
            er = [err_m(r["full"][m], r) for r in bench]
            rho = spearmanr(deficits[:, m_i], er).statistic
            print(f"  {m:22s} mean error {np.mean(er):5.1f} m, Spearman(deficit, error) {rho:+.2f}")
        print("  real flights, each member's error m / score (nats behind the best):")
        for r in real:
            tot = fold_scores(r, v).sum(axis=1)
            cells = [
                f"{m.replace('rfsl_spiral_', '')[:8]} {err_m(r['full'][m], r):5.1f}/"
                f"{t - tot.max():+4.1f}"
                for m, t in zip(MEMBERS, tot, strict=True)
            ]
            print(f"    {r['name'][5:]:10s} {'  '.join(cells[:3])}")
            print(f"    {'':10s} {'  '.join(cells[3:])}")
    best = choose_on_dev(dev, SCHEMES)
    if best is not None:
        score_held_out(
            real,
            fresh,
            "cross-fitted",
            SCHEMES[best],
            lambda r: min(err_m(r["full"][m], r) for m in MEMBERS),
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
