"""Diagnose the sim-to-real gap of a propagation model on flights with known transmitter positions.

``rfsl gap LOG.csv [LOG2.csv ...] [--truth LAT,LON ...] [--base e2r] [--candidates all|a,b]
[--lock DB] [--report DIR]`` fits the free constants (RSS offset, optionally a slope), shows the
gap of free-space / two-ray / e2r, where the base model departs (block-bootstrap flags), ranks
candidate effects on held-out blocks, climbs the greedy ladder and reports the localization cost
of every rung.  ``--lock DB`` withholds the samples read with the receiver's lock lost.  ``rfsl
gap --selftest`` simulates flights with one effect withheld and checks that the diagnosis finds it
(confusion table).
"""

from __future__ import annotations

import argparse
from dataclasses import replace


def _input_arguments(parser: argparse.ArgumentParser) -> None:
    """The flights and their transmitters."""
    parser.add_argument("logs", nargs="*", help="flight logs (CSV with JSON sidecar)")
    parser.add_argument(
        "--truth",
        action="append",
        default=None,
        metavar="LAT,LON",
        help="transmitter position: once for all logs or once per log (default: the sidecar)",
    )
    parser.add_argument(
        "--truth-height", type=float, default=1.5, help="transmitter antenna height m (1.5)"
    )
    parser.add_argument(
        "--lock",
        type=float,
        default=None,
        metavar="DB",
        help="withhold the samples whose receiver quality (column rss_quality_db, from the AFAR "
        "import) is under DB: read with the lock lost (50 for the AFAR sounder)",
    )


def _model_arguments(parser: argparse.ArgumentParser) -> None:
    """The base model, the candidates and how they are fitted and scored."""
    parser.add_argument(
        "--base", default="e2r", help="base model: free-space, two-ray or e2r (default e2r)"
    )
    parser.add_argument(
        "--pattern",
        default="dipole",
        help="antenna pattern of the base and reference models: isotropic, dipole, measured",
    )
    parser.add_argument(
        "--candidates", default="all", help="candidate effects, comma-separated, or all"
    )
    parser.add_argument(
        "--split",
        choices=("blocks", "flights"),
        default="blocks",
        help="held-out data: alternate contiguous chunks of every flight, or whole flights",
    )
    parser.add_argument(
        "--slope", action="store_true", help="also fit a per-flight path-gain slope"
    )
    parser.add_argument(
        "--loss", choices=("l2", "soft_l1"), default="l2", help="fit/ranking loss (l2)"
    )
    parser.add_argument("--max-rungs", type=int, default=6, help="most effects the ladder adds (6)")
    parser.add_argument(
        "--no-localize", action="store_true", help="skip the localization cost per rung"
    )


def _output_arguments(parser: argparse.ArgumentParser) -> None:
    """What is written: the report folder, the physics family, JSON instead of tables."""
    parser.add_argument("--report", metavar="DIR", help="write PNG plots and gap.json here")
    parser.add_argument(
        "--family",
        metavar="F.json",
        help="also fit a physics family (schema 1) from the ladder's effects, per flight, and "
        "write it",
    )
    parser.add_argument(
        "--family-name", default="family", help="the family's name in F.json (family)"
    )
    parser.add_argument(
        "--family-repeats",
        type=int,
        default=4,
        help="simulated copies of every track in the family's loop check (4; 0 = no check)",
    )
    parser.add_argument(
        "--family-structure",
        action="store_true",
        help="draw per-flight structure (a smooth gain drift over the flight) beside the "
        "shadowing, which keeps only what is left",
    )
    parser.add_argument(
        "--family-radial",
        action="store_true",
        help="per-flight structure with a smooth profile over the distance to the rover beside "
        "the drift (structure about the transmitter; implies --family-structure)",
    )
    parser.add_argument(
        "--family-path-shadowing",
        action="store_true",
        help=(
            "draw the shadowing along each flight's path (correlated along the track, independent "
            "on a later pass over the same ground: what the diagnosis calls 'correlated within "
            "flights') instead of fixed to the ground"
        ),
    )
    parser.add_argument(
        "--family-marginal",
        action="store_true",
        help=(
            "draw the shadowing with the shape of the real flights' held-out residual (skewed "
            "to fades) instead of a Gaussian one"
        ),
    )
    parser.add_argument(
        "--family-exponential",
        action="store_true",
        help=(
            "fit and draw the shadowing with an exponential covariance (rough, Gudmundson's) "
            "instead of a Gaussian one (smooth)"
        ),
    )
    parser.add_argument(
        "--family-azimuth",
        action="store_true",
        help="per-flight structure with a ripple over the rover's body azimuth beside the drift "
        "(an antenna pattern fixed to the body; implies --family-structure)",
    )
    parser.add_argument(
        "--json",
        action="store_true",
        help="print the summary of gap.json (ladder, rankings, named, structure) instead of tables",
    )


def _run_arguments(parser: argparse.ArgumentParser) -> None:
    """How the diagnosis runs: sample rate, threads, processes, seed."""
    parser.add_argument(
        "--rate-hz",
        type=float,
        default=3.0,
        help="thin flights to at most this sample rate first (3; 0 = every sample)",
    )
    parser.add_argument("--workers", type=int, default=1, help="threads for the candidate fits (1)")
    parser.add_argument(
        "--processes",
        type=int,
        default=1,
        help="processes for the candidate fits (1; results bit-identical to one process)",
    )
    parser.add_argument("--seed", type=int, default=0, help="bootstrap seed (0)")


def _selftest_arguments(parser: argparse.ArgumentParser) -> None:
    """The self-test on simulated flights."""
    parser.add_argument(
        "--selftest",
        action="store_true",
        help="simulate flights with each effect withheld and check the diagnosis finds it",
    )
    parser.add_argument("--seeds", default="1,2", help="self-test seeds (1,2)")
    parser.add_argument(
        "--withheld", default="all", help="self-test cases: effect names, none, or all"
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``rfsl gap`` options, in the order ``--help`` lists them."""
    _input_arguments(parser)
    _model_arguments(parser)
    _output_arguments(parser)
    _run_arguments(parser)
    _selftest_arguments(parser)
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing --family file or the report files in --report",
    )


# a --report folder holding one of these is a previous report
REPORT_FILES = (
    "gap.json",
    "selftest.json",
)


def check_outputs(args) -> None:
    """--report, --family and the counts checked before any work (a fit takes minutes): --report
    a folder that can be written and holds no earlier report unless --overwrite, --family a new
    file."""
    from pathlib import Path

    from mission.defaults import MAX_WORKERS
    from mission.errors import InputError
    from mission.files import check_out_file, check_writable_dir

    if not args.rate_hz >= 0 or args.rate_hz == float("inf"):
        raise InputError(
            f"must be a finite rate >= 0 (0: every sample), got {args.rate_hz}", field="--rate-hz"
        )
    if not 1 <= args.workers <= MAX_WORKERS:
        raise InputError(f"must be 1..{MAX_WORKERS}, got {args.workers}", field="--workers")
    if not 1 <= args.processes <= MAX_WORKERS:
        raise InputError(f"must be 1..{MAX_WORKERS}, got {args.processes}", field="--processes")
    for name in ("max_rungs", "family_repeats"):
        if getattr(args, name) < 0:
            raise InputError(
                f"must be >= 0, got {getattr(args, name)}", field="--" + name.replace("_", "-")
            )
    if args.report:
        rep = check_writable_dir(Path(args.report), "--report")
        old = [f for f in REPORT_FILES if (rep / f).exists()]
        if old and not args.overwrite:
            raise InputError(
                f"holds an earlier report ({old[0]}); use --overwrite or another folder",
                source=str(rep),
                field="--report",
            )
    if args.family:
        check_out_file(args.family, "--family", args.overwrite)


# fewer cannot support block splits and the per-effect fits (a 1-row log raised numpy errors)
MIN_SAMPLES = 200


def _parse_latlon(s: str):
    from mission.errors import InputError

    try:
        lat, lon = (float(v) for v in s.split(","))
    except ValueError:
        raise InputError(f"--truth must be LAT,LON, got {s!r}", field="truth") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise InputError(f"--truth out of range: {s!r}", field="truth")
    return lat, lon


def load_flights(
    paths: list[str], truths: list[str] | None, height: float, lock_db: float | None = None
):
    """Flight logs -> ``FlightSamples`` objects with their transmitter truth in each log's ENU
    frame; ``lock_db``: only the samples the receiver read locked (``align.locked_rows``)."""
    from mission.cli.main import print_notes
    from mission.errors import InputError
    from mission.flightlog import read_flight_log
    from mission.gap.align import flight_from_log, locked_rows

    if truths and len(truths) not in (1, len(paths)):
        raise InputError(
            f"give --truth once or once per log ({len(paths)}), got {len(truths)}", field="truth"
        )
    flights, quality = [], []
    for k, p in enumerate(paths):
        log = read_flight_log(p)
        print_notes(log.notes)
        quality.append(_quality(log))
        if lock_db is not None:
            log = locked_rows(log, lock_db)
        tx = None
        if truths:
            lat, lon = _parse_latlon(truths[0 if len(truths) == 1 else k])
            o = log.origin
            tx = o.to_enu(lat, lon, o.alt_m + height)
        f = flight_from_log(log, tx)
        if len(f.t_s) < MIN_SAMPLES:
            raise InputError(
                f"only {len(f.t_s)} samples with RSS; the gap diagnosis needs at least "
                f"{MIN_SAMPLES}",
                source=str(p),
            )
        flights.append(f)
    from mission.gap.labels import short_labels

    labels = short_labels([f.name for f in flights])
    print_notes(_lock_notes(labels, quality, lock_db))
    return [replace(f, name=lab) for f, lab in zip(flights, labels, strict=True)]


def _quality(log):
    """The log's receiver quality per row (``rss_quality_db``), or None when it has none."""
    import numpy as np

    from mission.flightlog.schema import QUALITY_COLUMN

    return np.asarray(log[QUALITY_COLUMN], dtype=float) if QUALITY_COLUMN in log.columns else None


def _lock_notes(labels: list[str], quality: list, lock_db: float | None) -> list[str]:
    """Short lines on the samples read with the receiver's lock lost: how many ``--lock``
    withholds from each flight, or, without it, each flight where a tenth or more were and a hint
    (NaN quality counts as lost)."""
    from mission.flightlog.schema import SOUNDER_LOCK_DB, out_of_lock

    if lock_db is not None:
        return [
            f"{lab}: --lock {lock_db:g} withholds {int(out_of_lock(q, lock_db).sum())} of "
            f"{q.size} samples"
            for lab, q in zip(labels, quality, strict=True)
            if q is not None
        ]
    lost = [
        (lab, float(out_of_lock(q).mean()))
        for lab, q in zip(labels, quality, strict=True)
        if q is not None and q.size
    ]
    out = [
        f"{lab}: {100 * u:.0f} % of samples read with the lock lost (quality < "
        f"{SOUNDER_LOCK_DB:g} dB)"
        for lab, u in lost
        if u >= 0.1
    ]
    if out:
        out.append(
            f"those read 23-37 dB low on AFAR flights; --lock {SOUNDER_LOCK_DB:g} withholds them"
        )
    return out


def _selftest(args) -> int:
    import time

    from rich.console import Console

    from mission.errors import InputError
    from mission.gap.fit import FitConfig
    from mission.gap.selftest import WITHHELD_ALL, confusion, run_selftest

    c = Console()
    check_outputs(args)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        raise InputError(
            f"expected comma-separated integers, got {args.seeds!r}", field="--seeds"
        ) from None
    if args.withheld == "all":
        cases = [*WITHHELD_ALL, None]
    else:
        cases = [None if w.strip() == "none" else w.strip() for w in args.withheld.split(",")]
        bad = [w for w in cases if w is not None and w not in WITHHELD_ALL]
        if bad:
            raise InputError(f"unknown withheld effect(s) {bad}", field="withheld")
    t0 = time.time()

    def progress(r) -> None:
        mark = "[green]PASS" if r.passed else "[red]FAIL"
        c.print(
            f"{mark}[/] withheld={r.withheld or 'none'} seed={r.seed} "
            f"first={r.ranked_first or 'none'} "
            f"significant={r.significant} rms {r.rms_base:.2f} -> {r.rms_after:.2f} dB; "
            f"{r.param_text} "
            f"({time.time() - t0:.0f} s)"
        )

    results = run_selftest(cases, seeds, None, progress)
    rows, cols, M = confusion(results)
    c.print(confusion_table(rows, cols, M))
    n_pass = sum(r.passed for r in results)
    c.print(f"{n_pass}/{len(results)} cases passed")
    if args.report:
        import json
        from pathlib import Path

        from mission.files import write_text

        out = Path(args.report)
        write_text(
            out / "selftest.json",
            json.dumps(
                {
                    "cases": [r.as_dict() for r in results],
                    "confusion": {"rows": rows, "cols": cols, "counts": M.tolist()},
                    "config": FitConfig().__dict__,
                },
                indent=1,
                default=str,
            ),
        )
        c.print(f"wrote {out / 'selftest.json'}")
    return 0 if n_pass == len(results) else 1


def confusion_table(rows: list[str], cols: list[str], M):
    """The self-test's confusion as a rich Table that reads at 80 columns: the columns are numbered
    and the rows carry the number of their effect, so no effect name is cut (14 named columns took
    150)."""
    from rich import box
    from rich.table import Table

    t = Table(
        title="Confusion: withheld (rows) vs ranked first and significant",
        box=box.SIMPLE_HEAD,
        show_edge=False,
        padding=(0, 0, 0, 1),
        pad_edge=False,
        caption="columns: " + ", ".join(f"{j + 1} {c}" for j, c in enumerate(cols)),
        caption_justify="left",
    )
    t.add_column("withheld", no_wrap=True)
    for j in range(len(cols)):
        t.add_column(str(j + 1), justify="right", no_wrap=True, min_width=2)
    for i, r in enumerate(rows):
        num = f"{cols.index(r) + 1:>2} " if r in cols else "   "
        t.add_row(
            num + r,
            *[
                (f"[bold]{v}" if v and (r == cols[j]) else ("." if not v else f"[red]{v}"))
                for j, v in enumerate(M[i])
            ],
        )
    return t


def _write_family(d, cfg, args, console) -> None:
    """Fit the ladder's effects per flight into a physics family and write it (validated by
    ``load_family``)."""
    import json
    import sys
    from datetime import UTC, datetime
    from pathlib import Path

    from mission.gap.familyfit import structure_of
    from mission.gap.familyrun import family_from_diagnosis
    from mission.physics.family import PhysicsFamily

    cmd = "rfsl " + " ".join(sys.argv[1:]) if len(sys.argv) > 1 and sys.argv[1] == "gap" else None
    src = {
        "kind": "rfsl gap --family",
        "command": cmd,
        "created": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "files": [str(p) for p in args.logs],
        "base": args.base,
        "pattern": args.pattern,
        "split": args.split,
        "loss": args.loss,
        "rate_hz": args.rate_hz,
    }
    rec = family_from_diagnosis(
        d,
        cfg,
        name=args.family_name,
        source=src,
        check=args.family_repeats > 0,
        repeats=max(args.family_repeats, 1),
        structure=structure_of(args.family_structure, args.family_radial, args.family_azimuth),
        shadowing_over="path" if args.family_path_shadowing else "ground",
        marginal=args.family_marginal,
        covariance="exponential" if args.family_exponential else "gaussian",
    )
    PhysicsFamily.from_dict(rec, source=args.family)  # refuse to write a family that would not load
    from mission.files import write_text

    out = write_text(Path(args.family), json.dumps(rec, indent=1) + "\n", field="--family")
    console.print(
        f"wrote {out} (effects: {', '.join(rec['effects']) or 'none'}; "
        f"{len(rec['per_flight'])} flights)"
    )
    lc = rec["checks"].get("loop")
    if lc:
        p = lc["heldout_p90_db"]
        bad = [k for k, v in lc["params"].items() if not v["inside"]]
        console.print(
            f"loop check ({'passed' if lc['passed'] else 'FAILED'}): simulated flights re-fit "
            "inside the "
            f"intervals{' except ' + ', '.join(bad) if bad else ''}; held-out p90 "
            f"{p['sim']:.1f} vs real "
            f"{p['real']:.1f} dB; sill {lc['sill_db']['sim']:.1f} dB, range "
            f"{lc['range_m']['sim']:.0f} m "
            f"({'inside' if lc['sill_db']['inside'] and lc['range_m']['inside'] else 'NOT inside'} "
            "the real intervals)"
        )
        cal = rec.get("residual_calibration")
        if cal:
            console.print(
                f"  (after {max(len(cal.get('steps', [])) - 1, 1)} recalibration step(s): the "
                "total "
                f"residual std scaled x{cal['p90_scale']:.2f}, checked on fresh draws)"
            )


def run(args) -> int:
    from mission.errors import InputError

    if args.selftest:
        return _selftest(args)
    if not args.logs:
        raise InputError("give at least one flight log (or --selftest)", field="logs")
    if args.lock is not None:
        from mission.cli.main import check_number

        check_number(args.lock, "--lock")
    check_outputs(args)
    import numpy as np
    from rich.console import Console

    from mission.gap.candidates import select
    from mission.gap.diagnose import base_pipeline, diagnose
    from mission.gap.fit import FitConfig
    from mission.gap.report import write_report
    from mission.gap.text import print_report

    try:
        base = base_pipeline(args.base, args.pattern)
    except (ValueError, KeyError) as e:
        raise InputError(str(e), field="base") from None
    flights = load_flights(args.logs, args.truth, args.truth_height, args.lock)
    cands = select(args.candidates)
    cfg = FitConfig(
        split=args.split,
        slope=args.slope,
        loss=args.loss,
        seed=args.seed,
        rate_hz=args.rate_hz,
        workers=args.workers,
        processes=args.processes,
    )
    err = Console(stderr=True)
    try:
        d = diagnose(
            flights,
            base,
            cands,
            cfg,
            base_label=f"{args.base}({args.pattern})",
            pattern=args.pattern,
            max_rungs=args.max_rungs,
            localize=not args.no_localize,
            progress=err.is_terminal,
        )
    except np.linalg.LinAlgError as e:
        raise InputError(
            f"the fit is singular on these flights ({e}): too short, or too little ground covered",
            source=", ".join(args.logs),
        ) from None
    c = err if args.json else Console()
    if not args.json:
        print_report(d, c)
    if args.report:
        for p in write_report(d, args.report):
            c.print(f"wrote {p}")
    if args.family:
        _write_family(d, cfg, args, c)
    if args.json:
        from mission import jsonsafe
        from mission.gap.report import summary

        print(jsonsafe.dumps(summary(d), indent=1))
    return 0
