"""Which point should the self-calibrating search report? MAP against posterior means, inside the
default fusion.

Why: on the benchmark the MAP jumps between modes of a flat likelihood and a posterior mean hedges;
on real flights the posteriors are wide.  The stop-17 rule (models/README.md) scores each candidate
as the selfcal component of the fusion = mean(selfcal point, network), on the benchmark (U) and the
six real flights (R): score U/min(U) + R/min(R), the incumbent MAP kept unless another is lower by
more than 0.05.

    rfsl dataset --suite unseen --logs --n 200 --seed 2026 --out /tmp/suite_2026
    # 2 min
    python experiments/point_estimates.py --suite-dir /tmp/suite_2026 \
        --mat ../shared/data/afar2023/mat
"""

from __future__ import annotations

import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

# the command line and flight loading it shares with the benchmarks (benchmarks/_scoring.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _scoring import flight_with_truth, scoring_parser

from mission.localize.api import localize_log
from mission.localize.selfcal import CALIBRATED_MASS
from mission.workshop.evaluate import import_afar

CANDIDATES = ("MAP", "PM", "C50", "C90")


def candidates(est) -> dict[str, np.ndarray]:
    """The four points of one fusion estimate: its selfcal MAP and three posterior means (log ENU
    m)."""
    post = est.posterior
    p, g = post.prob.ravel(), post.grid.reshape(-1, 2)
    out = {"MAP": np.asarray(est.extras["components"]["selfcal"]), "PM": p @ g / p.sum()}
    for level, key in ((0.5, "C50"), (0.9, "C90")):
        m = p >= post.mass_threshold(CALIBRATED_MASS[level])
        out[key] = p[m] @ g[m] / p[m].sum()
    return out


def one(job: tuple[str, str, int]) -> dict:
    """Fusion on one flight -> the candidates, the network's point and the truth."""
    kind, src, i = job
    log, truth = flight_with_truth(kind, src, i)
    est = localize_log(log, method="fusion")
    net = next(np.asarray(v) for k, v in est.extras["components"].items() if k != "selfcal")
    return {"truth": truth, "net": net, **candidates(est)}


def errors(rows: list[dict], key: str, fused: bool = True) -> np.ndarray:
    """2D errors (m) of candidate ``key``, fused with the network (or alone)."""
    return np.array(
        [np.hypot(*((0.5 * (r[key] + r["net"]) if fused else r[key]) - r["truth"])) for r in rows]
    )


def main() -> None:
    args = scoring_parser(__doc__).parse_args()

    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(args.workers) as ex:
        real = list(ex.map(one, [("real", str(p), 0) for p in import_afar(args.mat, tmp)]))
        bench = list(ex.map(one, [("suite", args.suite_dir, i) for i in range(args.n)]))
    u = {k: errors(bench, k).mean() for k in CANDIDATES}
    r = {k: errors(real, k).mean() for k in CANDIDATES}
    for k in CANDIDATES:
        eu, er = errors(bench, k), errors(real, k)
        print(
            f"{k:4s} fusion U {eu.mean():.1f} / {np.median(eu):.1f} / "
            f"{np.percentile(eu, 90):.1f}  R {er.mean():.1f}"
            f"  score {u[k] / min(u.values()) + r[k] / min(r.values()):.3f}  | selfcal alone U "
            f"{errors(bench, k, False).mean():.1f} R {errors(real, k, False).mean():.1f}  | R "
            "per flight "
            f"{' '.join(f'{e:.1f}' for e in er)}"
        )


if __name__ == "__main__":
    main()
