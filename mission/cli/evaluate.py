"""Compare localizers (ONNX networks, classical estimators) on simulated test sets and real flights.

The paper's table on one command: {free-space, two-ray, e2r} training data x {clustering, normalised
RSS, classical} x trajectories, on held-out simulated test sets (``--sim-test``, or generated here
with ``--trajectories``) and on real flights with truth (``--real LOG.csv``, or ``--afar DIR`` to
import the AFAR MAT files with the README's truth table).  Mean, median and 90th-percentile error in
metres.
"""

from __future__ import annotations

import argparse

from mission.localize.methods import names_where


def add_arguments(p: argparse.ArgumentParser) -> None:
    classical = names_where(kind="classical")
    p.add_argument("--models", nargs="*", default=[], help="ONNX models to compare")
    p.add_argument(
        "--methods",
        default=",".join(classical),
        help=f"classical methods, comma list of {', '.join(classical)}, grid:MODEL "
        "(free-space, two-ray, e2r) "
        "or grid:preset:NAME ('' for none)",
    )
    p.add_argument(
        "--sim-test", nargs="*", default=[], help="simulated test dataset folder(s) (rfsl dataset)"
    )
    p.add_argument(
        "--trajectories",
        nargs="*",
        default=[],
        help="generate a test set per generator here (with --mission, --sim-n, --sim-seed)",
    )
    p.add_argument(
        "--mission", default="missions/spiral.yaml", help="mission for generated test sets"
    )
    p.add_argument(
        "--sim-n", type=int, default=300, help="positions per generated test set (default 300)"
    )
    p.add_argument(
        "--sim-seed", type=int, default=1000, help="seed of generated test sets (default 1000)"
    )
    p.add_argument(
        "--sim-model", default="e2r", help="propagation model of generated test sets (default e2r)"
    )
    p.add_argument(
        "--n-classical",
        type=int,
        default=50,
        help="simulated flights per test set for the classical methods (default 50; grid is slow)",
    )
    p.add_argument(
        "--real", nargs="*", default=[], help="real flight logs (CSV) with truth in the sidecar"
    )
    p.add_argument(
        "--afar", help="folder of AFAR MAT files: import them (truth from the README table) and add"
    )
    p.add_argument(
        "--workdir",
        default=None,
        help="where imported logs / generated test sets go (default: temp)",
    )
    p.add_argument("--workers", type=int, default=2, help="workers for generated test sets")
    p.add_argument("--out", help="JSON report path")
    g = p.add_argument_group(
        "unseen-flight benchmark (mission.workshop.suite; models/README.md)",
        "with --afar DIR or --real LOGS: also the posterior-predictive checks of the "
        "benchmark's family against those real flights (mission.workshop.predictive)",
    )
    g.add_argument(
        "--suite", choices=("unseen",), help="run the methods (and --models) on the benchmark"
    )
    g.add_argument("--n", type=int, default=200, help="benchmark flights (default 200)")
    g.add_argument(
        "--seed", type=int, default=None, help="benchmark seed (default 2026, the benchmark's)"
    )
    g.add_argument(
        "--suite-dir",
        help="cached benchmark logs (rfsl dataset --suite unseen --logs); implies --suite",
    )
    g.add_argument(
        "--family",
        default="afar",
        metavar="FAMILY",
        help="physics family: a built-in one (mission.workshop.suite.FAMILIES; default afar) or a "
        "family file F.json (implies --suite unseen; with --suite-dir: must be the cache's)",
    )
    g.add_argument(
        "--by",
        default="",
        help="comma list of draw axes to break the mean error down by, e.g. "
        "tx_outside_flight_area,heading_habit,altitude_m,physics.rx_antenna",
    )


def _table(rows, title: str):
    from rich.table import Table

    t = Table(title=title)
    for c in ("test", "method", "train data", "features", "n", "mean m", "median m", "p90 m"):
        # never cut
        t.add_column(c, justify="right" if c.endswith("m") or c == "n" else "left", overflow="fold")
    for r in rows:
        s = r.summary()
        t.add_row(
            s["test"],
            s["method"],
            s["train_model"] or "-",
            s["features"] or "-",
            str(s["n"]),
            *(f"{s[k]:.1f}" if k in s else "-" for k in ("mean_m", "median_m", "p90_m")),
        )
    return t


def run(args: argparse.Namespace) -> int:
    import sys
    import tempfile
    from pathlib import Path

    from rich.console import Console

    from mission.defaults import MAX_WORKERS
    from mission.errors import InputError
    from mission.workshop.evaluate import evaluate_real, evaluate_sim, write_report

    console = Console()
    if not 1 <= args.workers <= MAX_WORKERS:
        raise InputError(f"must be 1..{MAX_WORKERS}, got {args.workers}", field="--workers")
    if args.family.lower().endswith(".json") or args.suite or args.suite_dir:
        return _run_suite(args, console)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    _check_options(args, methods)
    work = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="rfsl-eval-"))
    work.mkdir(parents=True, exist_ok=True)
    tests = _sim_tests(args, work, console)
    logs, notes = _real_flights(args, work)
    if not tests and not logs:
        raise InputError("nothing to evaluate: give --sim-test, --trajectories, --real or --afar")

    def say(msg: str) -> None:
        console.print(f"[dim]{msg}", highlight=False) if sys.stdout.isatty() else None

    rows = []
    for t in tests:
        rows += evaluate_sim(args.models, t, methods, args.n_classical, progress=say)
    real_rows = evaluate_real(args.models, logs, methods, progress=say) if logs else []
    _print_results(console, rows, real_rows, logs, notes)
    if args.out:
        write_report(
            rows + real_rows,
            args.out,
            {"command": " ".join(sys.argv), "notes": notes, "real_logs": logs, "sim_tests": tests},
        )
        console.print(f"report: {args.out}")
    return 0


def _check_options(args: argparse.Namespace, methods: list[str]) -> None:
    """Refuse an unknown method, a missing model file or an unwritable --out before the (long)
    evaluation."""
    from pathlib import Path

    from mission.errors import InputError
    from mission.workshop.evaluate import parse_method

    for m in methods:
        parse_method(m)
    for mp in args.models:
        if not Path(mp).is_file():
            raise InputError("no such model file", source=mp)
    if args.out:  # checked before the (long) evaluation, not after it
        from mission.cli.main import out_parent_ok

        if Path(args.out).is_dir():
            raise InputError(
                "is a directory; give a JSON file name such as report.json",
                source=args.out,
                field="--out",
            )
        out_parent_ok(Path(args.out))


def _sim_tests(args: argparse.Namespace, work, console) -> list[str]:
    """The simulated test sets: --sim-test folders, and one generated per --trajectories entry
    (kept in the work folder, made once)."""
    from mission.workshop.dataset import DatasetConfig, Randomisation, generate_dataset

    tests = list(args.sim_test)
    for traj in args.trajectories:
        d = work / f"test_{args.sim_model}_{traj}_n{args.sim_n}_s{args.sim_seed}"
        if not (d / "manifest.json").exists():
            console.print(f"generating {args.sim_n} simulated {traj} flights -> {d}")
            cfg = DatasetConfig(
                args.mission,
                args.sim_n,
                model=args.sim_model,
                seed=args.sim_seed,
                randomisation=Randomisation(trajectories=(traj,)),
            )
            generate_dataset(cfg, d, workers=args.workers, overwrite=True)
        tests.append(str(d))
    return tests


def _real_flights(args: argparse.Namespace, work) -> tuple[list[str], list[str]]:
    """The real logs (--real, and --afar's MAT files imported into the work folder) and the
    caveats of their truths."""
    from pathlib import Path

    from mission.workshop.evaluate import afar_truth, import_afar

    logs = list(args.real)
    notes = []
    if args.afar:
        logs += [str(p) for p in import_afar(args.afar, work / "afar_logs")]
        for p in logs:
            _, caveat = afar_truth(p)
            if caveat:
                notes.append(f"{Path(p).stem}: {caveat}")
    return logs, notes


def _print_results(console, rows, real_rows, logs, notes) -> None:
    """The simulated and real tables, each real flight's error per method, and the notes."""
    if rows:
        console.print(_table(rows, "simulated test sets (2D error)"))
    if real_rows:
        console.print(_table(real_rows, f"real flights ({len(logs)}; 2D error)"))
        for r in real_rows:
            per = ", ".join(
                f"{n.replace('results_useful_ori_', '')}: {e:.1f}"
                for n, e in zip(r.names, r.errors, strict=True)
            )
            console.print(f"  {r.method}: {per}", highlight=False)
    for n in notes:
        console.print(f"[yellow]note: {n}")


def _run_suite(args: argparse.Namespace, console) -> int:
    """``rfsl evaluate --suite unseen``: every method on the benchmark flights, one table."""
    import sys

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from mission.errors import InputError
    from mission.workshop.evaluate import write_report
    from mission.workshop.evaluate_suite import evaluate_suite

    methods = [m.strip() for m in args.methods.split(",") if m.strip()] + [
        f"onnx:{m}" for m in args.models
    ]
    if args.n < 1:
        raise InputError(f"--n must be >= 1, got {args.n}", field="--n")
    cols = (
        TextColumn("[bold]unseen flights"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("eta"),
        TimeRemainingColumn(),
    )
    stale: list[str] = []

    # a cache written by other simulator code: one stderr line, before the table
    def warn(
        text: str,
    ) -> None:
        stale.append(text)
        print(f"warning: {text}", file=sys.stderr)

    real_logs = _real_logs(args)
    stats: list | None = [] if real_logs else None
    with Progress(*cols, console=console, transient=True, disable=not console.is_terminal) as prog:
        task = prog.add_task("suite", total=args.n)
        rows, secs = evaluate_suite(
            methods,
            args.n,
            args.seed,
            args.suite_dir,
            family=args.family,
            workers=args.workers,
            progress=lambda d, _t: prog.update(task, completed=d),
            warn=warn,
            stats_out=stats,
        )
    console.print(_suite_table(rows, secs))
    extra: dict = {"command": " ".join(sys.argv), "seconds_per_flight": secs}
    if stale:
        extra["warnings"] = stale
    breakdowns = _breakdowns(args, rows, console)
    if breakdowns is not None:
        extra["breakdown"] = breakdowns
    if real_logs:
        extra["predictive_checks"] = _predictive(real_logs, methods, rows, stats, console)
    if args.out:
        write_report(rows, args.out, extra)
        console.print(f"report: {args.out}")
    return 0


def _suite_table(rows, secs: dict):
    """The benchmark's table: per method n, mean / median / p90 error, the share of truths in the
    50 % and 90 % regions, seconds per flight."""
    from rich.markup import escape
    from rich.table import Table

    t = Table(title=escape(f"{rows[0].test} (2D error; regions: share of truths inside)"))
    for c in ("method", "n", "mean m", "median m", "p90 m", "in 50 %", "in 90 %", "s/flight"):
        t.add_column(c, justify="left" if c == "method" else "right", overflow="fold")
    for r in rows:
        s = r.summary()
        cov = [f"{100 * s[k]:.0f} %" if k in s else "-" for k in ("coverage_50", "coverage_90")]
        t.add_row(
            escape(s["method"]),
            str(s["n"]),
            *(f"{s[k]:.1f}" for k in ("mean_m", "median_m", "p90_m")),
            *cov,
            f"{secs[s['method']]:.2f}",
        )
    return t


def _breakdowns(args: argparse.Namespace, rows, console) -> dict | None:
    """``--by AXES``: mean error per group of each draw axis, printed as a table per axis; None
    without --by."""
    from rich.markup import escape
    from rich.table import Table

    from mission.workshop.evaluate_suite import breakdown, suite_draws

    axes = [a.strip() for a in args.by.split(",") if a.strip()]
    if not axes:
        return None
    draws = suite_draws(len(rows[0].errors), args.seed, args.suite_dir, family=args.family)
    out: dict = {}
    for axis in axes:
        bd = breakdown(rows, draws, axis)
        out[axis] = bd
        bt = Table(title=escape(f"mean error (m) by {axis}"))
        bt.add_column(axis, overflow="fold")
        bt.add_column("n", justify="right")
        for r in rows:
            bt.add_column(escape(r.method), justify="right", overflow="fold")
        for g, d in bd.items():
            bt.add_row(escape(g), str(d["n"]), *(f"{d[r.method]:.1f}" for r in rows))
        console.print(bt)
    return out


def _real_logs(args: argparse.Namespace) -> list[str]:
    """Real logs with truth for the benchmark's posterior-predictive checks (``--real``,
    ``--afar``)."""
    import tempfile
    from pathlib import Path

    logs = list(args.real)
    if args.afar:
        from mission.workshop.evaluate import import_afar

        work = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="rfsl-eval-"))
        logs += [str(p) for p in import_afar(args.afar, work / "afar_logs")]
    return logs


def _predictive(real_logs: list[str], methods: list[str], rows, stats: list, console) -> dict:
    """Real flights vs the benchmark drawn from the family (``mission.workshop.predictive``): table
    + verdict."""
    from mission.workshop.predictive import checks_table, family_checks, score_real, verdict

    rstats, rerr = score_real(real_logs, methods)
    checks = family_checks(rstats, stats, rerr, {r.method: r.errors for r in rows})
    console.print(
        checks_table(
            checks,
            f"posterior-predictive checks: {len(real_logs)} real flights vs "
            f"{len(stats)} benchmark flights",
        )
    )
    line = verdict(checks)
    console.print(line, highlight=False)
    return {
        "checks": checks,
        "verdict": line,
        "real_logs": real_logs,
        "real_statistics": rstats,
        "real_errors_m": rerr,
        "benchmark_statistics": stats,
    }
