"""Link budget for one geometry: RSS (dBm) of the free-space, two-ray or enhanced two-ray model.

Positions are local ENU metres (z = height above ground); attitude is roll, pitch, yaw in degrees
(yaw clockwise from north). ``--explain`` shows each effect's contribution (path lengths, Gamma,
antenna gains, shadowing loss).

Example: ``rfsl rss --model e2r --tx 0,0,1.5 --rx 120,40,30 --attitude 2,-3,90 --explain``
"""

from __future__ import annotations

import argparse
import math

from mission.errors import InputError

MAX_COORD_M = 1e6  # beyond this a local ENU coordinate is a unit error (the models then give NaN)
MIN_DISTANCE_M = (
    0.1  # the far-field models are meaningless closer than this (tx == rx gave 242 dBm)
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from mission.cli.main import model_name_arg

    parser.add_argument(
        "--model",
        type=model_name_arg,
        default="e2r",
        help="propagation model: free-space, two-ray, e2r (default e2r)",
    )
    parser.add_argument(
        "--tx", required=True, metavar="X,Y,Z", help="transmitter position, ENU metres"
    )
    parser.add_argument(
        "--rx", required=True, metavar="X,Y,Z", help="receiver (UAV) position, ENU metres"
    )
    parser.add_argument(
        "--attitude",
        metavar="ROLL,PITCH,YAW",
        default=None,
        help="UAV attitude, degrees (MAVLink, yaw clockwise from north); default level",
    )
    parser.add_argument(
        "--antenna",
        default="dipole",
        metavar="dipole|isotropic|measured|PATH",
        help="antenna pattern at both ends: built-in name, pattern CSV or AERPAW file",
    )
    parser.add_argument(
        "--beta", type=float, default=None, help="leg-shadowing exponent beta (e2r)"
    )
    parser.add_argument(
        "--pt-dbm", type=float, default=None, help="transmit power (default 41 dBm)"
    )
    parser.add_argument(
        "--fc-hz", type=float, default=None, help="carrier frequency (default 3.32e9 Hz)"
    )
    parser.add_argument(
        "--eps-r", type=float, default=None, help="ground relative permittivity (default 2)"
    )
    parser.add_argument(
        "--sigma", type=float, default=None, help="ground conductivity S/m (default 0)"
    )
    parser.add_argument("--explain", action="store_true", help="show every effect's contribution")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")


def parse_triple(text: str | None, name: str) -> tuple[float, float, float]:
    """'a,b,c' -> three finite floats; InputError naming the argument otherwise."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 3:
        raise InputError(f"expected three comma-separated numbers, got {text!r}", field=name)
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        raise InputError(f"not a number in {text!r}", field=name) from None
    if not all(math.isfinite(v) for v in vals):
        raise InputError(f"non-finite value in {text!r}", field=name)
    return vals  # type: ignore[return-value]


def run(args: argparse.Namespace) -> int:
    import json

    import numpy as np

    from mission.physics import make_model

    tx, rx, att_deg = check_geometry(args)
    check_parameters(args)
    kw = {
        k: v
        for k, v in (
            ("beta", args.beta),
            ("pt_dbm", args.pt_dbm),
            ("fc_hz", args.fc_hz),
            ("eps_r", args.eps_r),
            ("sigma_s_m", args.sigma),
        )
        if v is not None
    }
    model = make_model(args.model, pattern=args.antenna, dtype=np.float64, **kw)
    tx_a = np.asarray(tx)
    rx_a = np.asarray([rx])
    att = np.radians([att_deg])
    rss = float(model.rss_dbm(tx_a, rx_a, att)[0])
    parts = {k: np.asarray(v).ravel()[0].item() for k, v in model.explain(tx_a, rx_a, att).items()}
    if args.json:
        out = {"model": model.name, "effects": list(model.names), "rss_dbm": rss}
        if args.explain:
            out["explain"] = parts
        print(json.dumps(out, indent=2))
        return 0
    if not args.explain:
        print(f"{rss:.2f} dBm")
        return 0
    _print_table(model, parts, rss)
    return 0


def check_geometry(args: argparse.Namespace) -> tuple:
    """--tx, --rx and --attitude parsed and checked (local positions above ground, far enough
    apart; degrees, not radians): (tx, rx, attitude in degrees)."""
    tx = parse_triple(args.tx, "--tx")
    rx = parse_triple(args.rx, "--rx")
    att_deg = (
        parse_triple(args.attitude, "--attitude") if args.attitude is not None else (0.0, 0.0, 0.0)
    )
    for flag, p in (("--tx", tx), ("--rx", rx)):
        if max(abs(v) for v in p) > MAX_COORD_M:
            raise InputError(
                f"coordinates beyond {MAX_COORD_M:g} m from the origin are not a local position, "
                f"got {p}",
                field=flag,
            )
        if p[2] < 0:
            raise InputError(
                f"height {p[2]:g} m is below ground (z is the height above ground)", field=flag
            )
    if math.dist(tx, rx) < MIN_DISTANCE_M:
        raise InputError(
            f"transmitter and receiver are {math.dist(tx, rx):.3g} m apart; the propagation models "
            f"need at least {MIN_DISTANCE_M:g} m",
            field="--rx",
        )
    if max(abs(a) for a in att_deg[:2]) > 180 or abs(att_deg[2]) > 720:
        raise InputError(
            "roll/pitch within +-180 and yaw within +-720 degrees expected (radians?), got "
            f"{att_deg}",
            field="--attitude",
        )
    return tx, rx, att_deg


def check_parameters(args: argparse.Namespace) -> None:
    """The model parameters given (--fc-hz, --eps-r, --pt-dbm, --beta, --sigma) within their
    ranges."""
    for flag, val, lo, hi in (
        ("--fc-hz", args.fc_hz, 1e6, 3e11),
        ("--eps-r", args.eps_r, 1.0, 1e4),
    ):
        if val is not None and not (math.isfinite(val) and lo <= val <= hi):
            raise InputError(f"must be a number within {lo:g}..{hi:g}, got {val}", field=flag)
    for flag, val, lim in (
        ("--pt-dbm", args.pt_dbm, 200.0),
        ("--beta", args.beta, 100.0),
        ("--sigma", args.sigma, 1e9),
    ):
        if val is not None and not (
            math.isfinite(val) and abs(val) <= lim and (flag == "--pt-dbm" or val >= 0)
        ):
            raise InputError(
                f"must be a finite number {'within +-' if flag == '--pt-dbm' else '0..'}{lim:g}, "
                f"got {val}",
                field=flag,
            )


def _print_table(model: object, p: dict, rss: float) -> None:
    from rich.table import Table

    from mission.cli.main import console

    deg = math.degrees
    t = Table(title=f"{model.name}: {rss:.2f} dBm", show_lines=False)  # type: ignore[attr-defined]
    for col in ("effect", "quantity", "value"):
        t.add_column(col)
    names = model.names  # type: ignore[attr-defined]
    t.add_row(
        "geometry",
        "d_2d / d_los / d_ref",
        f"{p['d_2d']:.2f} / {p['d_los']:.2f} / {p['d_ref']:.2f} m",
    )
    t.add_row("free_space", "direct ray (with gains)", f"{p['direct_dbm']:.2f} dBm")
    if "ground_reflection" in names:
        t.add_row("ground_reflection", "grazing angle", f"{deg(p['grazing_rad']):.2f} deg")
        t.add_row("", "Gamma", f"|{p['gamma_abs']:.3f}| at {deg(p['gamma_phase_rad']):.1f} deg")
        t.add_row(
            "",
            "phase difference k(d_ref - d_los)",
            f"{deg(p['phase_diff_rad']) % 360:.1f} deg (mod 360)",
        )
        t.add_row("", "reflected ray (with gains, Gamma)", f"{p['reflected_dbm']:.2f} dBm")
        t.add_row("", "coherent sum", f"{p['two_ray_dbm']:.2f} dBm")
    if "tx_antenna" in names:
        t.add_row(
            "tx_antenna",
            "gain direct / reflected",
            f"{p['g_tx_dir_dbi']:.2f} / {p['g_tx_ref_dbi']:.2f} dBi",
        )
    if "rx_antenna" in names:
        t.add_row(
            "rx_antenna",
            "gain direct / reflected",
            f"{p['g_rx_dir_dbi']:.2f} / {p['g_rx_ref_dbi']:.2f} dBi",
        )
    t.add_row(
        "attitude" if "attitude" in names else "(level frame)",
        "az_b / dep_b of the LOS",
        f"{deg(p['az_b_rad']):.1f} / {deg(p['dep_b_rad']):.1f} deg",
    )
    if "leg_shadowing" in names:
        t.add_row(
            "leg_shadowing",
            "shadowed / Upsilon",
            f"{bool(p['shadowed'])} / {p['upsilon_db']:.2f} dB",
        )
    t.add_row("total", "RSS", f"{rss:.2f} dBm")
    console().print(t)
