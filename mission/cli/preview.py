"""Plot a mission (areas, waypoints, simulated path, time budget) and, with --accuracy, expected
error.

Also prints a summary table: length, duration, RSS samples, and how close the path comes to each
part of the rover area.  The accuracy heatmap uses the model-based estimator of ``mission.preview``.
An adaptive mission (``--adaptive`` or ``adaptive: {enabled: true}``) adds its expected error
against the fixed trajectory's on paired simulated flights (``mission.adaptive.preview``).
"""

from __future__ import annotations

import argparse

MAX_PIXELS = 8000  # per side: 100000x100000 ran until killed


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mission", help="mission YAML file (e.g. missions/spiral.yaml)")
    parser.add_argument("--out", default="preview.png", help="PNG to write (default preview.png)")
    parser.add_argument(
        "--accuracy",
        action="store_true",
        help="add a heatmap of expected localization error over the rover area",
    )
    parser.add_argument(
        "--grid",
        type=int,
        default=12,
        help="transmitter lattice is GRID x GRID over the rover area (default 12)",
    )
    parser.add_argument(
        "--seed", type=int, default=None, help="random seed (default: the mission's seed)"
    )
    parser.add_argument(
        "--size", default="1200x1000", help="image size in pixels WxH (default 1200x1000)"
    )
    parser.add_argument(
        "--adaptive",
        action="store_true",
        help="compare the adaptive finish (the mission's adaptive: block) with the fixed "
        "trajectory on simulated flights (also when the block says enabled: true)",
    )
    parser.add_argument(
        "--flights",
        type=int,
        default=6,
        help="simulated flights for the adaptive comparison (default 6, about 7 s each)",
    )
    parser.add_argument(
        "--family", default="afar", help="physics family of those flights (default afar)"
    )


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from mission.cli.main import console as make_console
    from mission.cli.main import image_out
    from mission.preview import render_preview, summarize
    from mission.spec import load_mission

    w, h = check_options(args)
    image_out(args.out)
    spec = load_mission(args.mission)
    seed = spec.source.seed if args.seed is None else args.seed
    summary = summarize(spec)
    console = make_console()

    emap = error_map(args, spec, seed, console) if args.accuracy else None

    console.print(summary_table(args, spec, seed, summary, emap, console))

    render_preview(
        spec,
        args.out,
        error_map=emap,
        summary=summary,
        rng=np.random.default_rng(seed),
        size_px=(w, h),
    )
    console.print(f"wrote {args.out}")
    return 0


def check_options(args: argparse.Namespace) -> tuple[int, int]:
    """Refuse a bad --size, --grid or --seed (``InputError`` naming it); the image size."""
    from mission.errors import InputError

    try:
        w, h = (int(v) for v in str(args.size).lower().split("x"))
        if not (200 <= w <= MAX_PIXELS and 200 <= h <= MAX_PIXELS):
            raise ValueError
    except ValueError:
        raise InputError(
            f"expected WxH pixels (each 200..{MAX_PIXELS}), got '{args.size}'", field="--size"
        ) from None
    if not 2 <= args.grid <= 200:
        raise InputError(f"must be 2..200, got {args.grid}", field="--grid")
    if args.seed is not None and args.seed < 0:
        raise InputError(f"must be >= 0, got {args.seed}", field="--seed")
    return w, h


def error_map(args: argparse.Namespace, spec, seed: int, console):
    """--accuracy: the expected-error map over a --grid lattice, with a progress bar."""
    import numpy as np

    from mission.console import progress_bar
    from mission.preview import expected_error_map

    with progress_bar("expected error", console) as prog:
        task = prog.add_task("grid", total=args.grid)
        return expected_error_map(
            spec,
            args.grid,
            np.random.default_rng(seed),
            progress=lambda done, total: prog.update(task, completed=done),
        )


def summary_table(args: argparse.Namespace, spec, seed: int, summary, emap, console):
    """The mission's figures as a table: path, duration against the budget, samples, fence
    clearance, coverage, expected error, the adaptive comparison when asked, flyable."""
    from rich.table import Table

    from mission.preview import ESTIMATOR_NOTE

    table = Table(title=f"mission {spec.name} ({spec.trajectory.generator}, {spec.altitude_m:g} m)")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    used = summary.duration_s / summary.time_budget_s
    table.add_row("waypoints", str(summary.n_waypoints))
    table.add_row("path length (take-off to landing)", f"{summary.length_m:,.0f} m")
    table.add_row(
        "estimated duration", f"{summary.duration_s:.0f} s ({summary.duration_s / 60:.1f} min)"
    )
    table.add_row("time budget used", f"{used:.0%} of {summary.time_budget_s:g} s")
    table.add_row(f"RSS samples at {spec.source.sample_period_s:g} s", f"{summary.n_samples:,}")
    table.add_row(
        "fence clearance (min)",
        f"{summary.min_fence_clearance_m:.1f} m (margin {spec.fence_margin_m:g} m)",
    )
    table.add_row("rover area: worst point to path", f"{summary.coverage.max_m:.1f} m")
    table.add_row("rover area: mean distance to path", f"{summary.coverage.mean_m:.1f} m")
    for k, v in summary.coverage.quadrant_max_m.items():
        table.add_row(f"rover area {k} quadrant: worst point", f"{v:.1f} m")
    if emap is not None:
        table.add_row(
            f"expected error (mean / median), {ESTIMATOR_NOTE.format(model=spec.source.model)}",
            f"{emap.mean_m:.1f} / {emap.median_m:.1f} m",
        )
    if args.adaptive or (spec.adaptive is not None and spec.adaptive.enabled):
        from mission.adaptive.preview import adaptive_rows

        for k, v in adaptive_rows(spec, args.flights, seed, args.family, console):
            table.add_row(k, v)
    table.add_row(
        "flyable", "yes" if not summary.violations else f"[red]no: {summary.violations[0]}[/red]"
    )
    return table
