"""Summarise a flight log (rich table) and draw its path coloured by RSS (PNG)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", type=Path, help="flight log CSV (with its JSON sidecar)")
    parser.add_argument(
        "--out", type=Path, default=None, help="PNG to write (default: beside the log, .png)"
    )


def run(args: argparse.Namespace) -> int:
    from rich.table import Table

    from mission.cli.main import console, image_out, print_notes
    from mission.flightlog import read_flight_log
    from mission.replay import plot, summary

    png = image_out(args.out or Path(args.log).with_suffix(".png"))
    log = read_flight_log(args.log)
    print_notes(log.notes)
    s = summary(log)
    table = Table(title=f"flight {args.log}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for k, v in s.items():
        table.add_row(k, f"{v:.3f}" if isinstance(v, float) else str(v))
    console().print(table)
    png = plot(log, png)
    print(f"plot: {png}")
    return 0
