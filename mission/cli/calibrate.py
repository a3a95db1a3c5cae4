"""Calibrate a physics preset on real flights with known transmitters, with leave-one-group-out
figures.

``rfsl calibrate LOG.csv [LOG2.csv ...] --out my_preset.json [--groups REGEX] [--configs a,b,c]``
fits every configuration (``mission.calibrate.CONFIGS``) on all groups but one and scores the
held-out group, chooses the configuration with the lowest held-out soft-L1, refits it on all flights
and writes a preset file that records what it was fitted on and its held-out figures.  Use it with
``localize --physics-preset my_preset.json`` or ``rfsl dataset --physics my_preset.json``.
"""

from __future__ import annotations

import argparse
import textwrap


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "logs", nargs="+", help="flight logs with the transmitter truth in their sidecars"
    )
    parser.add_argument("--out", required=True, metavar="PRESET.json", help="preset file to write")
    parser.add_argument(
        "--name", default=None, help="preset name recorded in the file (default: the file stem)"
    )
    parser.add_argument(
        "--groups",
        default=None,
        metavar="REGEX",
        help="group of a flight = first capture group of REGEX in its file name (e.g. "
        "'exp_(\\d+)_' for AFAR teams); default: its folder when the logs lie in several "
        "folders, else every flight is its own group (leave one flight out)",
    )
    parser.add_argument(
        "--configs",
        default=None,
        help="configurations to compare, comma-separated (default: fs_iso, fs_slope, "
        "fs_rxflip, fs_rxflip_yaw, fs_rxflip_yaw_slope, fs_rxup_yaw)",
    )
    parser.add_argument(
        "--max-samples", type=int, default=1200, help="samples per flight used for fitting (1200)"
    )
    parser.add_argument("--force", action="store_true", help="overwrite an existing --out file")


def _groups(paths, regex: str | None) -> tuple[list[str], str]:
    import re

    from mission.errors import InputError

    if regex:
        try:
            rx = re.compile(regex)
        except re.error as e:
            raise InputError(f"bad regular expression: {e}", field="--groups") from None
        out = []
        for p in paths:
            m = rx.search(p.name)
            if m is None:
                raise InputError(
                    f"--groups {regex!r} does not match this file name",
                    source=str(p),
                    field="--groups",
                )
            out.append(m.group(1) if m.groups() else m.group(0))
        return out, f"groups from --groups {regex!r}"
    folders = [str(p.resolve().parent) for p in paths]
    if len(set(folders)) > 1:
        return [p.resolve().parent.name for p in paths], "one group per folder"
    return [p.stem for p in paths], "one group per flight (leave one flight out)"


def run(args: argparse.Namespace) -> int:
    """Check the arguments, read the flights, fit with held-out figures, write the preset and print
    the comparison."""
    import json
    import shlex
    import sys

    from rich.progress import Progress

    from mission.calibrate import calibrate, preset_record
    from mission.cli.main import console
    from mission.files import write_text

    out, configs, paths, groups, how = _checked(args)
    flights = _flights(paths)
    con = console(stderr=True)
    con.print(f"{len(flights)} flights, {len(set(groups))} groups ({how})")
    con.print(f"configurations: {', '.join(configs)}")
    with Progress(console=con, transient=True) as prog:
        task = prog.add_task("calibrating", total=len(configs))
        res = calibrate(
            flights,
            groups,
            configs,
            max_samples=args.max_samples,
            progress=lambda n: prog.update(task, description=f"held-out fits of {n}", advance=1),
        )
    cmd = "rfsl calibrate " + " ".join(shlex.quote(a) for a in sys.argv[2:])
    rec = preset_record(
        args.name or out.stem, res, flights, groups, cmd, data=", ".join(str(p) for p in paths)
    )
    write_text(out, json.dumps(rec, indent=1, default=float) + "\n", "--out")
    _print_result(res, out)
    return 0


def _checked(args: argparse.Namespace):
    """(out path, configurations, log paths, their groups, how they were grouped), or an
    InputError naming the argument."""
    from pathlib import Path

    from mission.calibrate import DEFAULT_CONFIGS, config
    from mission.cli.main import out_parent_ok
    from mission.errors import InputError

    out = Path(args.out)
    if out.suffix.lower() != ".json":
        raise InputError("the preset file must end in .json", source=str(out), field="--out")
    if out.is_dir() or (out.exists() and not args.force):
        raise InputError(
            "exists (use --force to overwrite)" if out.is_file() else "is a folder",
            source=str(out),
            field="--out",
        )
    out_parent_ok(out)
    if args.max_samples < 50:
        raise InputError(
            f"--max-samples must be at least 50, got {args.max_samples}", field="--max-samples"
        )
    configs = tuple(args.configs.split(",")) if args.configs else DEFAULT_CONFIGS
    for c in configs:
        config(c)
    paths = [Path(p) for p in args.logs]
    groups, how = _groups(paths, args.groups)
    if len(set(groups)) < 2:
        raise InputError(
            "held-out calibration needs flights of at least two groups", field="--groups"
        )
    return out, configs, paths, groups, how


def _flights(paths) -> list:
    """The logs' fitted samples as the gap's flights (each log read and validated)."""
    from mission.flightlog import read_flight_log
    from mission.gap.align import flight_from_log
    from mission.localize.preprocess import select_samples

    flights = []
    for p in paths:
        log = read_flight_log(p)
        part, _ = select_samples(log)
        flights.append(flight_from_log(part, name=p.stem))
    return flights


def _print_result(res: dict, out) -> None:
    """The held-out table of every configuration and the chosen one's parameters (80 columns)."""
    from rich.table import Table

    from mission.cli.main import console

    tab = Table(title="held-out fit (leave one group out): |measured - model - offset|")
    for col in ("configuration", "median dB", "p90 dB", "rms dB", "soft-L1"):
        tab.add_column(col)
    for name, row in res["configs"].items():
        p = row["pooled"]
        mark = " (chosen)" if name == res["chosen"] else ""
        tab.add_row(
            name + mark,
            f"{p['median_abs_db']:.2f}",
            f"{p['p90_abs_db']:.2f}",
            f"{p['rms_db']:.2f}",
            f"{p['soft_l1']:.2f}",
        )
    console().print(tab)
    params = ", ".join(
        f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in res["model"].items()
    )
    console().print(f"wrote {out}: {res['chosen']}")
    console().print(textwrap.fill(params, 80, initial_indent="  ", subsequent_indent="  "))
