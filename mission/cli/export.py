"""Export a mission as QGroundControl .plan, QGC WPL text, GeoJSON or KML (after the pre-flight checks).

A mission that fails the geofence, altitude or time-budget check is refused (exit code 2) and nothing is
written, unless --force is given.
"""

from __future__ import annotations

import argparse

FORMATS = ("plan", "wpl", "geojson", "kml")
SUFFIX = {"plan": ".plan", "wpl": ".waypoints", "geojson": ".geojson", "kml": ".kml"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mission", help="mission YAML file (e.g. missions/spiral.yaml)")
    parser.add_argument("--format", choices=FORMATS, default=None,
                        help="output format (default: from the --out suffix, else plan)")
    parser.add_argument("--out", default=None, help="output path (default: <mission name> + suffix)")
    parser.add_argument("--force", action="store_true", help="export even if the pre-flight checks fail")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from mission.spec import load_mission
    from mission.trajectory.checks import assert_flyable, check_mission
    from mission.trajectory.export import export_mission

    fmt = args.format
    if fmt is None:
        by_suffix = {v: k for k, v in SUFFIX.items()} | {".json": "geojson", ".txt": "wpl"}
        fmt = by_suffix.get(Path(args.out).suffix.lower(), "plan") if args.out else "plan"
    spec = load_mission(args.mission)
    rep = check_mission(spec) if args.force else assert_flyable(spec)
    out = Path(args.out) if args.out else Path(spec.name + SUFFIX[fmt])
    export_mission(spec, fmt, out)
    print(f"wrote {out} ({fmt}: {rep.n_waypoints} waypoints, {rep.length_m:.0f} m, "
          f"{rep.duration_s / 60:.1f} min{', FAILS CHECKS' if rep.violations else ''})")
    return 0
