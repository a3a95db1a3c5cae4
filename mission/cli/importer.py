"""Convert real flights (AFAR challenge MAT files) into the project's flight logs (CSV + JSON
sidecar).

Example: ``rfsl import afar-mat exp_288_loc_1.mat --out logs/ --truth 35.72806709,-78.69730398``.
The truth is taken only from ``--truth``, never guessed from the file name.
"""

from __future__ import annotations

import argparse
import textwrap

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError


def parse_latlon(text: str, name: str = "--truth") -> tuple[float, float]:
    """'LAT,LON' -> (lat, lon) in degrees, or InputError naming the option."""
    try:
        lat_s, lon_s = text.split(",")
        lat, lon = float(lat_s), float(lon_s)
    except ValueError:
        raise InputError(f"expects LAT,LON in degrees, got {text!r}", field=name) from None
    if not (abs(lat) <= 90 and abs(lon) <= 180):
        raise InputError(f"{text!r} is not a latitude,longitude pair in degrees", field=name)
    return lat, lon


def parse_origin(text: str, name: str = "--origin"):
    """'LAT,LON' or 'LAT,LON,ALT' (degrees, metres AMSL) -> ``Origin``, or InputError naming the
    option."""
    from mission.geo import Origin

    parts = str(text).split(",")
    if len(parts) not in (2, 3):
        raise InputError(f"expects LAT,LON[,ALT], got {text!r}", field=name)
    lat, lon = parse_latlon(",".join(parts[:2]), name)
    try:
        alt = float(parts[2]) if len(parts) == 3 else 0.0
    except ValueError:
        raise InputError(f"altitude is not a number in {text!r}", field=name) from None
    if not abs(alt) <= 20000:
        raise InputError(f"altitude {alt:g} m is not plausible", field=name)
    return Origin(lat, lon, alt)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "kind", choices=["afar-mat"], help="input format (AFAR challenge MAT files)"
    )
    parser.add_argument("files", nargs="+", metavar="FILE", help="input file(s)")
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="output directory for CSV + sidecar"
    )
    parser.add_argument(
        "--truth", metavar="LAT,LON", help="transmitter truth (applied to every file given)"
    )
    parser.add_argument(
        "--truth-height",
        type=float,
        default=DEFAULT_TX_HEIGHT_M,
        metavar="M",
        help=f"transmitter antenna height above ground (default {DEFAULT_TX_HEIGHT_M:g} m, "
        "AFAR rover)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing output logs")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from mission.cli.main import console as make_console
    from mission.cli.main import out_parent_ok
    from mission.importers.afar import import_afar_mat

    console = make_console()
    truth = parse_latlon(args.truth) if args.truth else None
    if not args.truth_height >= 0:
        raise InputError(
            f"transmitter height {args.truth_height:g} m is below ground", field="--truth-height"
        )
    out_parent_ok(Path(args.out), folder=True)
    files: list[Path] = []
    for f in map(Path, args.files):  # a folder stands for every .mat file in it
        if f.is_dir():
            mats = sorted(f.glob("*.mat"))
            if not mats:
                raise InputError("folder holds no .mat files", source=str(f))
            files += mats
        else:
            files.append(f)
    for f in files:  # every output checked before the first is written
        for p in (Path(args.out) / f"{f.stem}.csv", Path(args.out) / f"{f.stem}.json"):
            if p.exists() and not args.overwrite:
                raise InputError("output exists (use --overwrite)", source=str(p))
    for f in files:
        res = import_afar_mat(
            f, args.out, truth=truth, truth_height_m=args.truth_height, overwrite=args.overwrite
        )
        tr = "truth from --truth" if truth else "no truth"
        console.print(f"[green]wrote[/] {res.out_path}")
        console.print(f"  {len(res.log)} samples, {tr}{'' if res.notes else ', timestamps clean'}")
        for n in res.notes:  # one line each, folded at words to 80 columns
            console.print(textwrap.fill(n, 80, initial_indent="  note: ", subsequent_indent="    "))
    return 0
