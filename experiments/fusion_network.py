"""Which network should the default fusion use?  Each candidate network as the fusion's network
component.

Why: the real-log default is mean(selfcal point, network point); a new network replaces
``rfsl_spiral_e2r`` only under a rule written before scoring (models/README.md), which scores the
*fusion* on the unseen-flight benchmark (U) and the six real flights (R): score U/min(U) +
R/min(R) over the candidates.  The self-calibrating point is computed once per flight and shared by
all candidates.

    rfsl dataset --suite unseen --logs --n 200 --seed 2026 --out /tmp/suite_2026
    # ~1 min, 2 cores
    python experiments/fusion_network.py --suite-dir /tmp/suite_2026 \\
        --mat ../shared/data/afar2023/mat --nets models/rfsl_spiral_e2r.onnx M/candidate.onnx
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
from mission.threads import limit_worker
from mission.workshop.evaluate import import_afar

# 288 location 3 (suspect label, models/README.md): reported as the mean of the other five too
SUSPECT = 2


def one(job: tuple[str, str, int, tuple[str, ...]]) -> dict:
    """Selfcal point, each network's point and the truth on one flight (log ENU m)."""
    kind, src, i, nets = job
    log, truth = flight_with_truth(kind, src, i)
    sc = localize_log(log, method="selfcal")
    out = {"truth": truth, "selfcal": np.array([sc.x_m, sc.y_m])}
    for n in nets:
        e = localize_log(log, model_path=n)
        out[n] = np.array([e.x_m, e.y_m])
    return out


def errors(rows: list[dict], net: str, fused: bool = True) -> np.ndarray:
    """2D errors (m) of the fusion with ``net`` (or of ``net`` alone)."""
    return np.array(
        [
            np.hypot(*((0.5 * (r["selfcal"] + r[net]) if fused else r[net]) - r["truth"]))
            for r in rows
        ]
    )


def main() -> None:
    ap = scoring_parser(__doc__)
    ap.add_argument("--nets", nargs="+", required=True, help="ONNX networks (the incumbent first)")
    args = ap.parse_args()

    nets = tuple(args.nets)
    with (
        tempfile.TemporaryDirectory() as tmp,
        ProcessPoolExecutor(args.workers, initializer=limit_worker) as ex,
    ):
        real = list(ex.map(one, [("real", str(p), 0, nets) for p in import_afar(args.mat, tmp)]))
        bench = list(
            ex.map(one, [("suite", args.suite_dir, i, nets) for i in range(args.n)], chunksize=4)
        )
    u = {n: errors(bench, n).mean() for n in nets}
    r = {n: errors(real, n).mean() for n in nets}
    for n in nets:
        eu, er, au, ar = (
            errors(bench, n),
            errors(real, n),
            errors(bench, n, False),
            errors(real, n, False),
        )
        score = u[n] / min(u.values()) + r[n] / min(r.values())
        five, five_alone = np.delete(er, SUSPECT).mean(), np.delete(ar, SUSPECT).mean()
        print(
            f"{Path(n).name}: fusion U {eu.mean():.1f} / {np.median(eu):.1f} / "
            f"{np.percentile(eu, 90):.1f}  R "
            f"{er.mean():.1f} [{five:.1f}]  score {score:.3f}  | alone U {au.mean():.1f} / "
            f"{np.median(au):.1f}  "
            f"R {ar.mean():.1f} [{five_alone:.1f}]  | R per flight fused "
            f"{' '.join(f'{e:.1f}' for e in er)}; "
            f"alone {' '.join(f'{e:.1f}' for e in ar)}"
        )


if __name__ == "__main__":
    main()
