"""Export a mission as QGroundControl .plan, QGC WPL text, GeoJSON or KML (after the pre-flight
checks).

A mission that fails the geofence, altitude or time-budget check is refused (exit code 2) and
nothing is written, unless --force is given.  An existing output file is kept unless --overwrite is
given, and an --out suffix that does not match the format is refused (``x.gpx`` must not hold plan
JSON).
"""

from __future__ import annotations

import argparse

FORMATS = ("plan", "wpl", "geojson", "kml")
SUFFIX = {"plan": ".plan", "wpl": ".waypoints", "geojson": ".geojson", "kml": ".kml"}
BY_SUFFIX = {v: k for k, v in SUFFIX.items()} | {".json": "geojson", ".txt": "wpl", ".wpl": "wpl"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mission", help="mission YAML file (e.g. missions/spiral.yaml)")
    parser.add_argument(
        "--format",
        choices=FORMATS,
        default=None,
        help="output format (default: from the --out suffix, else plan)",
    )
    parser.add_argument(
        "--out", default=None, help="output path (default: <mission name> + suffix)"
    )
    parser.add_argument(
        "--force", action="store_true", help="export even if the pre-flight checks fail"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output file")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from mission.cli.main import out_parent_ok
    from mission.errors import InputError
    from mission.spec import load_mission
    from mission.trajectory.checks import assert_flyable, check_mission
    from mission.trajectory.export import export_mission

    fmt = args.format
    if args.out:
        suffix = Path(args.out).suffix.lower()
        known = ", ".join(f"{s} ({f})" for s, f in BY_SUFFIX.items())
        if suffix and suffix not in BY_SUFFIX:
            raise InputError(
                f"unknown export suffix '{suffix}'; use {known}", source=args.out, field="--out"
            )
        if fmt is not None and suffix and BY_SUFFIX[suffix] != fmt:
            raise InputError(
                f"suffix '{suffix}' is {BY_SUFFIX[suffix]}, but --format is {fmt}",
                source=args.out,
                field="--out",
            )
        fmt = fmt or BY_SUFFIX.get(suffix, "plan")
    fmt = fmt or "plan"
    spec = load_mission(args.mission)
    out = Path(args.out) if args.out else Path(spec.name + SUFFIX[fmt])
    if out.is_dir():
        raise InputError(
            f"is a directory; give a file name such as {out / (spec.name + SUFFIX[fmt])}",
            source=str(out),
            field="--out",
        )
    out_parent_ok(out)
    if out.exists() and not args.overwrite:
        raise InputError(
            "exists already (use --overwrite to replace it)", source=str(out), field="--out"
        )
    rep = check_mission(spec) if args.force else assert_flyable(spec)
    export_mission(spec, fmt, out)
    print(
        f"wrote {out} ({fmt}: {rep.n_waypoints} waypoints, {rep.length_m:.0f} m, "
        f"{rep.duration_s / 60:.1f} min{', FAILS CHECKS' if rep.violations else ''})"
    )
    return 0
