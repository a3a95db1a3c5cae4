"""Fly a mission in the fast kinematic simulator and write a flight log (CSV + JSON sidecar).

No MAVLink is involved: the vehicle follows the project's multicopter kinematics, RSS is sampled
every 0.03 s through the chosen propagation model with seeded attitude perturbation and noise.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def parse_xy(text: str, name: str) -> tuple[float, ...]:
    """Parse 'X,Y' or 'X,Y,Z' (metres) for a CLI option, with a one-line error naming the option."""
    from mission.errors import InputError

    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"expected comma-separated numbers, got {text!r}", field=name) from None
    if len(vals) not in (2, 3):
        raise InputError(f"expected X,Y or X,Y,Z in metres, got {len(vals)} value(s)", field=name)
    if not all(abs(v) < 1e6 for v in vals):  # also refuses nan and inf
        raise InputError(
            f"expected finite local coordinates (|value| < 1e6 m), got {text!r}", field=name
        )
    return vals


def add_arguments(p: argparse.ArgumentParser) -> None:
    from mission.cli.main import model_name_arg

    p.add_argument("mission", help="mission YAML file (e.g. missions/spiral.yaml)")
    p.add_argument(
        "--source",
        help="transmitter X,Y[,Z] in the mission's ENU frame, metres "
        "(default: the mission's source, or random in the rover area)",
    )
    p.add_argument(
        "--model",
        type=model_name_arg,
        help="propagation model: free-space, two-ray, e2r (default: mission's)",
    )
    p.add_argument("--seed", type=int, help="random seed (default: the mission's)")
    p.add_argument(
        "--cruise-only", action="store_true", help="fly only the trajectory, no take-off or return"
    )
    p.add_argument("--out", default="flights", help="output folder (default: flights/)")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from mission.cli.main import console, out_parent_ok
    from mission.errors import InputError
    from mission.flightlog import sidecar_path, write_flight_log
    from mission.physics import make_model
    from mission.simulate import simulate_flight
    from mission.spec import load_mission

    if args.seed is not None and args.seed < 0:
        raise InputError(f"must be >= 0, got {args.seed}", field="--seed")
    out_parent_ok(Path(args.out), folder=True)
    spec = load_mission(args.mission)
    seed = spec.source.seed if args.seed is None else args.seed
    rng = np.random.default_rng(seed)
    tx = transmitter(args, spec, seed)
    model_name = args.model or spec.source.model
    out = Path(args.out)
    csv = out / f"{spec.name}_sim_{model_name}_seed{seed}.csv"
    # before the work: neither half of an earlier log is replaced
    for p in (
        csv,
        sidecar_path(csv),
    ):
        if p.exists():
            raise InputError(
                "a flight log of this name exists already; choose another --out or --seed",
                source=str(p),
            )
    model = make_model(model_name, **spec.source.model_params)
    path = spec.waypoints_enu() if args.cruise_only else spec.flight_path_enu()
    flight = simulate_flight(path, tx, model, spec.sim_config(), rng)
    meta = sidecar_meta(spec, tx, model_name, seed)
    write_flight_log(csv, flight.log_columns(spec.field.origin), meta)
    c = console()
    c.print(
        f"simulated [bold]{spec.name}[/]: {flight.t_s[-1]:.0f} s, {len(flight.t_s)} RSS samples, "
        f"{flight.profile.length_m:.0f} m"
    )
    c.print(
        f"transmitter at ({tx[0]:.1f}, {tx[1]:.1f}) m, RSS {flight.rss_dbm.min():.1f} .. "
        f"{flight.rss_dbm.max():.1f} dBm ({model_name}, seed {seed})"
    )
    c.print(f"log: {csv}")
    return 0


def transmitter(args: argparse.Namespace, spec, seed: int):
    """``--source`` (checked against the field; outside the rover area only warned), else the
    mission's draw for ``seed``."""
    import numpy as np

    from mission.cli.main import console
    from mission.errors import InputError
    from mission.trajectory.checks import source_violations

    if args.source:
        v = parse_xy(args.source, "--source")
        tx = np.array([v[0], v[1], v[2] if len(v) == 3 else spec.source.tx_height_m])
        bad = source_violations(spec, tx)
        if bad:
            raise InputError(bad[0].message, field="--source")
        if not spec.field.rover_area.contains(tx[:2]):
            console(stderr=True).print(
                f"[yellow]warning: source {tx[:2].tolist()} is outside the rover area"
            )
    else:
        tx = spec.transmitter(seed)
        bad = source_violations(spec)
        if bad:
            raise InputError(bad[0].message, source=spec.source_name, field=bad[0].key)
    return tx


def sidecar_meta(spec, tx, model_name: str, seed: int) -> dict:
    """The simulated log's sidecar: the simulator, model, seed and noise, the true transmitter,
    the mission and its trajectory."""
    from mission.flightlog import make_meta

    lat, lon, _ = spec.field.origin.to_geodetic(tx)
    meta = make_meta(
        spec.field.origin,
        {
            "kind": "sim",
            "simulator": "kinematic",
            "model": model_name,
            "seed": seed,
            "model_params": spec.source.model_params,
            "noise_db": spec.sim_config().noise_db,
        },
        truth={
            "x_m": float(tx[0]),
            "y_m": float(tx[1]),
            "z_m": float(tx[2]),
            "lat_deg": float(lat),
            "lon_deg": float(lon),
            "height_m": float(tx[2]),
        },
        mission=str(spec.path) if spec.path else spec.name,
        trajectory=spec.trajectory_meta(),
    )
    return meta
