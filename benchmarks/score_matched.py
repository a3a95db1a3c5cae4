"""``localize --method matched`` on the six real flights and the first K flights of a benchmark
cache, paired with the methods of a ``score_decision.py --json`` run on the same flights (it trains
per flight, ~1 min each on 2 idle cores: too slow for the full 200-flight table on shared cores).

    python benchmarks/score_matched.py --suite-dir /tmp/suite_fam --n 10 \
        --mat ../shared/data/afar2023/mat --decision /tmp/decision.json --json /tmp/matched.json
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from _scoring import scoring_parser
from score_decision import INCUMBENT, score_real

from mission.evidence import compare_methods
from mission.workshop.evaluate_suite import evaluate_suite


def main() -> None:
    ap = scoring_parser(__doc__)
    ap.add_argument(
        "--decision", required=True, help="score_decision.py --json output on the same cache"
    )
    ap.add_argument("--json", help="write every figure here")
    ap.add_argument("--skip-real", action="store_true")
    args = ap.parse_args()
    dec = json.loads(Path(args.decision).read_text())
    out: dict = {"n_bench": args.n}
    if not args.skip_real:
        t0 = time.perf_counter()
        names, real, rcov, _ = score_real(args.mat, {"matched": "matched"})
        out.update(
            real_flights=names,
            real_errors_m=real["matched"],
            real_coverage=rcov["matched"],
            real_seconds=time.perf_counter() - t0,
        )
        errs = {INCUMBENT: dec["real_errors_m"][INCUMBENT], "matched": real["matched"]}
        cf, ct = (
            compare_methods(errs, INCUMBENT),
            compare_methods(errs, INCUMBENT, groups=dec["teams"]),
        )
        out["real"] = {
            "mean": cf["matched"]["mean"].to_dict(),
            "mean_teams": ct["matched"]["mean"].to_dict(),
            "diff": cf["matched"]["diff"].to_dict(),
            "diff_teams": ct["matched"]["diff"].to_dict(),
        }
        print(
            f"real: matched {cf['matched']['mean'].fmt()} m, vs default "
            f"{cf['matched']['diff'].fmt()} "
            f"(teams {ct['matched']['diff'].fmt()}); per flight "
            + ", ".join(f"{e:.1f}" for e in real["matched"]),
            flush=True,
        )
    if args.n > 0:
        t0 = time.perf_counter()
        rows, secs = evaluate_suite(
            ["matched"], args.n, suite_dir=args.suite_dir, workers=args.workers
        )
        e = list(rows[0].errors)
        errs = {k: v[: len(e)] for k, v in dec["bench_errors_m"].items()} | {"matched": e}
        cb = compare_methods(errs, INCUMBENT)
        cov = {lvl: float(np.mean(c)) for lvl, c in rows[0].covered.items()}
        out.update(
            bench_errors_m=e,
            bench_coverage=cov,
            bench_seconds_per_flight=secs["matched"],
            bench={k: {q: iv.to_dict() for q, iv in v.items()} for k, v in cb.items()},
            bench_wall_s=time.perf_counter() - t0,
        )
        print(
            f"benchmark (first {len(e)}): "
            + "; ".join(f"{k} {v['mean'].fmt()}" for k, v in cb.items())
        )
        print(f"matched vs default {cb['matched']['diff'].fmt()} m; regions 50/90 %: {cov}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
