"""The one table of every method and the default-changing rule applied (models/README.md, "Decisions
with error bars").

Every method on (a) the six shared real AFAR flights held out by team (LOTO) and (b) a benchmark
cache drawn from a physics family (``rfsl dataset --suite unseen --logs --family F.json``): mean
error with paired bootstrap 90 % intervals (real: over flights and over teams; benchmark: over
flights), the paired difference to the default, the share of truths in the 50 % / 90 % regions, then
``mission.workshop.decision.pooled_decision``.

    rfsl dataset --suite unseen --logs --family mission/data/afar_family.json --n 200 \
        --out /tmp/suite_fam
    python benchmarks/score_decision.py --suite-dir /tmp/suite_fam --n 200 \
        --mat ../shared/data/afar2023/mat --workers 2 --json /tmp/decision.json \
        --md /tmp/decision.md [--extra matched]
"""

from __future__ import annotations

import json
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from _scoring import scoring_parser

from mission.evidence import compare_methods
from mission.flightlog import read_flight_log
from mission.importers.afar import AFAR2023_FOLD_WITHOUT, AFAR2023_TRUTH, import_afar_mat
from mission.localize.api import localize_log
from mission.workshop.decision import pooled_decision
from mission.workshop.evaluate_suite import evaluate_suite, region_coverage, suite_method
from mission.workshop.predictive import family_checks, flight_statistics, verdict
from mission.workshop.suite_cache import read_suite

INCUMBENT = "fusion (default)"
NETS = ("rfsl_spiral_e2r", "rfsl_spiral_e2r_ens5", "rfsl_spiral_alt", "rfsl_default", "rfsl_afar")
# its physics was fitted on all real flights: shown, not a candidate
NOT_HELD_OUT = {"net rfsl_afar"}


def methods(models: Path, extra: list[str]) -> dict[str, str]:
    """Label -> benchmark method spec (``mission.workshop.evaluate_suite.suite_method``)."""
    out = {INCUMBENT: "default", "selfcal": "selfcal", "grid afar (LOTO fold on real)": "grid"}
    out.update(
        {
            f"net {n}": f"onnx:{models / (n + '.onnx')}"
            for n in NETS
            if (models / (n + ".onnx")).is_file()
        }
    )
    out["strongest sample"] = "strongest"
    out.update({m: m for m in extra})
    return out


def real_kwargs(spec: str, team: str) -> dict:
    """``localize_log`` arguments of method ``spec`` on a real flight of ``team``: the benchmark's
    (``suite_method``), but the grid's physics fitted on the other team (LOTO)."""
    if spec == "grid":
        return {"method": "grid", "physics_preset": f"afar:{AFAR2023_FOLD_WITHOUT[team]}"}
    return suite_method(spec)


def score_real(mat: str, specs: dict[str, str]) -> tuple[list[str], dict, dict, list[dict]]:
    """(flight names, {label: errors}, {label: {level: [covered]}}, predictive-check statistics per
    flight) on the six real flights, LOTO."""
    files = sorted(Path(mat).glob("results_useful_ori_exp_*_loc_*.mat"))
    if not files:
        raise SystemExit(f"no AFAR MAT files under {mat}")
    names, errs, cov, stats = [], {k: [] for k in specs}, {k: {} for k in specs}, []
    with tempfile.TemporaryDirectory() as tmp:
        for f in files:
            name = f.stem.replace("results_useful_ori_exp_", "")
            team, loc = name.split("_")[0], int(name.rsplit("_", 1)[1])
            log = import_afar_mat(f, tmp, truth=AFAR2023_TRUTH[loc]).out_path
            names.append(name)
            rl = read_flight_log(log)
            stats.append(flight_statistics(rl, rl.truth_enu[:2], float(rl.truth_enu[2])))
            for label, spec in specs.items():
                est = localize_log(log, **real_kwargs(spec, team))
                truth = np.array([est.extras["truth_x_m"], est.extras["truth_y_m"]])
                errs[label].append(float(np.hypot(est.x_m - truth[0], est.y_m - truth[1])))
                for lvl, c in region_coverage(est, truth).items():
                    cov[label].setdefault(lvl, []).append(bool(c))
    return names, errs, cov, stats


def _share(c: dict, lvl: str) -> float | None:
    v = c.get(lvl)
    return float(np.mean(v)) if v else None


def _cov(c: dict, n: int) -> str:
    parts = [
        f"{round(100 * s)} %" if (s := _share(c, lvl)) is not None and len(c[lvl]) == n else "-"
        for lvl in ("50", "90")
    ]
    return " / ".join(parts)


def main() -> None:
    ap = scoring_parser(__doc__)
    ap.add_argument("--json", help="write every figure here")
    ap.add_argument("--md", help="write the markdown table here")
    ap.add_argument(
        "--extra", default="", help="comma list of further localize methods (e.g. matched)"
    )
    ap.add_argument("--models", default=str(Path(__file__).resolve().parents[1] / "models"))
    args = ap.parse_args()
    specs = methods(Path(args.models), [m.strip() for m in args.extra.split(",") if m.strip()])
    t0 = time.perf_counter()
    names, real, rcov, rstats = score_real(args.mat, specs)
    t_real = time.perf_counter() - t0
    teams = [n.split("_")[0] for n in names]
    bstats: list[dict] = []
    rows, secs = evaluate_suite(
        list(dict.fromkeys(specs.values())),
        args.n,
        suite_dir=args.suite_dir,
        workers=args.workers,
        stats_out=bstats,
    )
    by_spec = {r.method: r for r in rows}
    bench = {k: list(by_spec[s].errors) for k, s in specs.items()}
    bcov = {k: by_spec[s].covered for k, s in specs.items()}
    n_b = len(bench[INCUMBENT])
    cf = compare_methods(real, INCUMBENT)
    ct = compare_methods(real, INCUMBENT, groups=teams)
    cb = compare_methods(bench, INCUMBENT)
    cands = {k: v for k, v in real.items() if k not in NOT_HELD_OUT}
    dec = pooled_decision(
        cands,
        teams,
        {k: bench[k] for k in cands},
        INCUMBENT,
        coverage_90={k: s for k in cands if (s := _share(bcov[k], "90")) is not None},
    )
    fam = read_suite(args.suite_dir).manifest.get("family")
    checks = family_checks(rstats, bstats, real, bench)
    head = (
        "| method | real LOTO mean m [90 % flights] [teams] | vs default, real | real in 50 / "
        "90 % | "
        f"benchmark ({fam}, n = {n_b}) mean m [90 %] | vs default, bench | bench in 50 / 90 % | "
        "pooled rel. diff [90 %] | rule |"
    )
    lines = [head, "|" + " --- |" * 9]
    for k in specs:
        d = dec["methods"].get(k)
        rule = "incumbent" if k == INCUMBENT else ("not held out" if d is None else d["reason"])
        pooled = (
            "-"
            if d is None
            else f"{100 * d['pooled'].value:+.0f} % [{100 * d['pooled'].lo:+.0f}, "
            f"{100 * d['pooled'].hi:+.0f}]"
        )
        lines.append(
            f"| {k} | {cf[k]['mean'].fmt()} [{ct[k]['mean'].lo:.1f}, {ct[k]['mean'].hi:.1f}] | "
            f"{'-' if k == INCUMBENT else cf[k]['diff'].fmt()} | {_cov(rcov[k], len(names))} | "
            f"{cb[k]['mean'].fmt()} | {'-' if k == INCUMBENT else cb[k]['diff'].fmt()} | "
            f"{_cov(bcov[k], n_b)} | {pooled} | {rule} |"
        )
    md = "\n".join(lines) + f"\n\nVerdict: {dec['why']} (choice: {dec['choice']}).\n"
    md += (
        "\n| check | real mean | benchmark 10-90 % | real inside | p | passes |\n|"
        + " --- |" * 6
        + "\n"
    )
    md += "".join(
        f"| {k} | {c['real_mean']:.1f} | {c['band'][0]:.1f}-{c['band'][1]:.1f} | {c['inside']} of "
        f"{c['n_real']} | {c['p']:.2f} | {'yes' if c['passes'] else 'no'} |\n"
        for k, c in checks.items()
    )
    md += f"\n{verdict(checks)}.\n"
    print(
        textwrap.fill(
            f"real flights scored in {t_real:.0f} s; benchmark seconds per flight: "
            + ", ".join(f"{k.split(' (')[0]} {secs[s]:.2f}" for k, s in specs.items()),
            80,
        )
    )
    print(f"{'method':26s} {'real':>6s} {'bench':>6s}  rule")
    for k in specs:
        print(
            f"{k[:26]:26s} {np.mean(real[k]):6.1f} {np.mean(bench[k]):6.1f}  "
            f"{dec['methods'][k]['reason'][:36] if k in dec['methods'] else '-'}"
        )
    print(textwrap.fill(f"verdict: {dec['why']}", 80))
    print(textwrap.fill(verdict(checks), 80))
    if args.md:
        Path(args.md).write_text(md)
    if args.json:
        iv = {
            k: {s: {q: x.to_dict() for q, x in v.items()} for s, v in src.items()}
            for k, src in (("real_flights", cf), ("real_teams", ct), ("bench", cb))
        }
        Path(args.json).write_text(
            json.dumps(
                {
                    "suite_dir": args.suite_dir,
                    "family": fam,
                    "n_bench": n_b,
                    "real_flights": names,
                    "teams": teams,
                    "real_errors_m": real,
                    "bench_errors_m": bench,
                    "real_coverage": rcov,
                    "bench_coverage": bcov,
                    "intervals": iv,
                    "seconds_per_flight": {k: secs[s] for k, s in specs.items()},
                    "predictive_checks": checks,
                    "predictive_verdict": verdict(checks),
                    "real_statistics": rstats,
                    "bench_statistics": bstats,
                    "decision": {
                        "choice": dec["choice"],
                        "changed": dec["changed"],
                        "why": dec["why"],
                        "methods": {
                            k: {
                                **{q: v[q].to_dict() for q in ("real", "bench", "pooled")},
                                "wins": v["wins"],
                                "reason": v["reason"],
                            }
                            for k, v in dec["methods"].items()
                        },
                    },
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
