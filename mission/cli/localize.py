"""Estimate the transmitter position from a flight log (ONNX network or classical estimators).

Keeps the cruise part of the log (mission legs, else the cruise altitudes) and runs the method.
Default method (``mission.localize.api.localize_log``): ``--model`` given -> that network; a real
receiver's log -> ``fusion`` (mean of the self-calibrating grid and
``models/rfsl_spiral_e2r.onnx``); a simulated log -> the shipped ``models/rfsl_default.onnx`` when
present, else a grid search with the log's own simulation model. The grid's physics: ``--physics`` /
``--physics-preset``, by default the simulator's model for a simulated log and the calibrated
``afar`` preset for a real one.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.localize.methods import METHOD_NAMES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="flight log (CSV with its JSON sidecar)")
    parser.add_argument(
        "--model",
        metavar="MODEL.onnx",
        help="ONNX localizer (implies --method onnx; with --method fusion: the fused network)",
    )
    parser.add_argument(
        "--method",
        choices=METHOD_NAMES,
        metavar="METHOD",
        help=f"localizer: {', '.join(METHOD_NAMES)} (default: fusion for a real receiver's "
        "log; for a "
        "simulated log the shipped network trained on that kind of flight, else grid)",
    )
    parser.add_argument(
        "--physics",
        default=None,
        metavar="NAME",
        help="propagation model of the grid search (free-space, two-ray, e2r; default: a "
        "simulated log's own "
        "model, else the afar preset)",
    )
    parser.add_argument(
        "--physics-preset",
        default=None,
        metavar="NAME",
        help="calibrated physics preset of the grid search (afar; the default for a real log "
        "without --physics)",
    )
    parser.add_argument(
        "--tx-height",
        type=float,
        default=DEFAULT_TX_HEIGHT_M,
        metavar="M",
        help=f"transmitter antenna height for the grid search (default {DEFAULT_TX_HEIGHT_M:g} m)",
    )
    parser.add_argument(
        "--truth", metavar="LAT,LON", help="true transmitter position (overrides the sidecar)"
    )
    parser.add_argument(
        "--origin",
        metavar="LAT,LON[,ALT]",
        help="mission origin (degrees, m AMSL) for a log without a sidecar (overrides the "
        "sidecar's)",
    )
    parser.add_argument(
        "--no-cruise", action="store_true", help="use all samples (no cruise selection)"
    )
    parser.add_argument(
        "--at",
        type=float,
        default=None,
        metavar="T",
        help="the estimate the flight had at log time T s: rows up to T only, with the method the "
        "flight's live estimates used (fly-mission's sidecar: 'estimates'), else the default",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", metavar="OUT.png", help="draw flight, clusters and estimate")


def run(args: argparse.Namespace) -> int:
    from mission.cli.main import print_notes
    from mission.flightlog import read_flight_log

    truth, origin = check_options(args)
    log = read_flight_log(args.log, origin=origin)
    print_notes(log.notes)
    method = args.method
    if args.at is not None:  # what the flight knew at T (mission.flight.live)
        from mission.flight.live import log_at, recorded_method

        log, method = log_at(log, args.at, str(args.log)), method or recorded_method(log.meta)
    est = estimate(args, log, method, truth)
    if args.plot:
        plot(args, log, est)
    if args.json:
        import json

        d = est.to_dict()
        d["notes"] = list(log.notes)
        print(json.dumps(d, default=float))
        return 0
    from mission.cli.main import console

    console().print(table(args, log, est))
    return 0


def check_options(args: argparse.Namespace):
    """Refuse a bad option before the log is read (``InputError`` naming it); resolves
    ``args.model`` to its file. Returns (truth, origin)."""
    import math

    from mission.cli.importer import parse_latlon, parse_origin
    from mission.cli.main import image_out
    from mission.errors import InputError

    truth = parse_latlon(args.truth) if args.truth else None
    origin = parse_origin(args.origin) if args.origin else None
    method = args.method
    if args.model and method not in (None, "onnx", "fusion"):
        raise InputError(f"--model needs --method onnx or fusion (got --method {method})")
    if args.model:  # rfsl_default.onnx from any folder: the shipped network of that name
        from mission.shipped import resolve_shipped

        args.model = str(resolve_shipped(args.model, "models", ".onnx"))
    if not (math.isfinite(args.tx_height) and 0 <= args.tx_height <= 1000):
        raise InputError(
            f"transmitter height must be 0..1000 m above ground, got {args.tx_height:g}",
            field="--tx-height",
        )
    if args.physics is not None:
        from mission.physics.propagation import canonical_model_name

        try:
            args.physics = canonical_model_name(args.physics)
        except ValueError as e:
            raise InputError(str(e), field="--physics") from None
    if args.physics_preset is not None:
        from mission.physics.presets import load_preset

        try:
            load_preset(args.physics_preset)
        except InputError as e:
            raise InputError(str(e).split(": ", 1)[-1], field="--physics-preset") from None
    if args.plot:
        image_out(args.plot, "--plot")
    return truth, origin


def estimate(args: argparse.Namespace, log, method: str | None, truth):
    """``localize_log`` on the log with the options; numpy's warnings are shown after it, and a
    refusal that names nothing names the log."""
    import warnings

    from mission.errors import InputError
    from mission.localize.api import localize_log

    # numpy's warnings on a too-short log: the error says it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            est = localize_log(
                log,
                method=method,
                model_path=args.model,
                truth=truth,
                cruise=not args.no_cruise,
                physics_model=args.physics,
                tx_height_m=args.tx_height,
                physics_preset=args.physics_preset,
            )
        except InputError as e:
            if e.source or e.field:
                raise
            # "only 5 grouped samples" names the log
            raise InputError(str(e), source=str(args.log)) from None
    for w in caught:
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return est


def plot(args: argparse.Namespace, log, est) -> None:
    """``--plot``: the samples the estimate used, its clusters and the estimate, drawn to
    ``args.plot``."""
    from mission.localize.api import search_area
    from mission.localize.features import FeatureConfig
    from mission.localize.plot import plot_localization
    from mission.localize.preprocess import select_samples

    part = log if args.no_cruise else select_samples(log)[0]  # the samples the estimate used
    fc = est.extras.get("feature_config")
    cfg = FeatureConfig.from_dict(fc) if fc else None
    plot_localization(part, est, args.plot, cfg=cfg, area=search_area(log))
    est.extras["plot"] = str(args.plot)


def table(args: argparse.Namespace, log, est):
    """The estimate as the text table a user reads (rich ``Table``)."""
    from rich.table import Table

    from mission.flightlog import WARNING
    from mission.localize.render import Shown

    tab = Table(title=f"transmitter estimate: {args.log}", show_header=False)
    tab.add_row("method", f"{est.method}" + (f" ({est.model})" if est.model else ""))
    tab.add_row("why", str(est.extras.get("method_choice", "")))
    shown = Shown.of(est)
    for row in shown.rows():
        tab.add_row(*row)
    if est.selection is not None:
        tab.add_row("samples", est.selection.line())
    if est.fit is not None:
        tab.add_row("fit", est.fit.line())
    for row in shown.region_rows():
        tab.add_row(*row)
    if est.candidates:
        tab.add_row(
            "candidates",
            "\n".join(c.line() for c in est.candidates[:3])
            + (f"\n(+{len(est.candidates) - 3} more in --json)" if len(est.candidates) > 3 else ""),
        )
    elif est.components:
        parts = [f"{n} {e.x_m:.1f}, {e.y_m:.1f} m" for n, e in est.components.items()]
        tab.add_row(
            "components", "; ".join(parts) + f" ({est.extras['component_distance_m']:.0f} m apart)"
        )
    if "p_outside_flown_area" in est.extras:
        tab.add_row("outside flown area", f"probability {est.extras['p_outside_flown_area']:.2f}")
    # matched: how it did on simulated transmitters of this track
    if est.extras.get("sim_check", {}).get("n"):
        sc = est.extras["sim_check"]
        tab.add_row(
            "simulated check",
            f"median error {sc['median_error_m']:.0f} m on {sc['n']} simulated "
            f"transmitters along this track (family {est.extras.get('family')})",
        )
    if est.notes:
        tab.add_row("[bold]note", " ".join(est.notes))
    if args.plot:
        tab.add_row("plot", str(args.plot))
    if "warning" in est.extras:
        tab.add_row("[bold yellow]warning", f"[yellow]{est.extras['warning']}")
    for n in log.notes:  # also on stderr; repeated here because the table is what a user reads
        kind, _, text = n.partition(": ") if n.startswith(WARNING) else ("note", "", n)
        tab.add_row(f"[bold yellow]{kind}" if kind != "note" else kind, f"[yellow]{text}")
    return tab


def main(argv: Sequence[str] | None = None) -> int:
    """Console script ``localize``."""
    from mission.cli.main import standalone_main

    return standalone_main("localize", sys.modules[__name__], argv)


if __name__ == "__main__":
    sys.exit(main())
