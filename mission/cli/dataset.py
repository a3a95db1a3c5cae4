"""Generate a simulated dataset: N transmitter positions, each flown in the simulator, stored as
feature chunks.

Every flight has its own seed (``SeedSequence(seed).spawn(N)[i]``), so the bytes do not depend on
the number of workers.  Randomisation flags widen the simulated domain towards real flights (see
``mission.workshop.dataset``); ``--randomise`` switches on the project's recommended set at once.
"""

from __future__ import annotations

import argparse

from mission.defaults import DEFAULT_TX_HEIGHT_M


def _range(text: str) -> tuple[float, float]:
    """'LO,HI' or a single value -> (lo, hi)."""
    vals = [float(v) for v in text.split(",")]
    if len(vals) == 1:
        return (vals[0], vals[0])
    if len(vals) != 2 or vals[1] < vals[0]:
        raise argparse.ArgumentTypeError(f"expected LO,HI with LO <= HI, got {text!r}")
    return (vals[0], vals[1])


MAX_FLIGHTS = 1_000_000  # one dataset's flights (the largest shipped training set is far smaller)


def add_arguments(p: argparse.ArgumentParser) -> None:
    from mission.cli.main import model_name_arg

    p.add_argument(
        "mission",
        nargs="?",
        help="mission YAML (field, altitude, trajectory, source defaults); not with --suite",
    )
    p.add_argument("--n", type=int, required=True, help="number of transmitter positions (flights)")
    p.add_argument(
        "--model",
        default="e2r",
        type=model_name_arg,
        help="propagation model: free-space, two-ray, e2r (aliases as make_model)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="dataset seed (default 0; with --suite --logs 2026, the benchmark's own)",
    )
    p.add_argument("--out", required=True, help="output folder (manifest.json + chunk_*.npz)")
    p.add_argument("--chunk", type=int, default=500, help="flights per chunk file (default 500)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument(
        "--features",
        default="clustering,normalised_rss",
        help="comma list of stored inputs: clustering, normalised_rss (default both)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing dataset in --out")
    p.add_argument(
        "--arc-step",
        type=float,
        default=0.0,
        metavar="M",
        help="clustering features: resample each flight to one point per M metres of path first "
        "(speed/hover invariant; 0 = off, the paper's features)",
    )
    p.add_argument(
        "--physics",
        metavar="PRESET",
        help="calibrated physics preset instead of --model: afar, or a fold such as afar:fit328 "
        "(fitted on team 328 only; score the result on the other team's flights)",
    )
    add_suite_arguments(p)
    add_randomisation_arguments(p)


def add_suite_arguments(p: argparse.ArgumentParser) -> None:
    """The unseen-flight benchmark family's options (--suite, --logs, --family, --center)."""
    s = p.add_argument_group("unseen-flight benchmark family (mission.workshop.suite)")
    s.add_argument(
        "--suite",
        choices=("unseen",),
        help="flights drawn from the benchmark's family (every axis "
        "randomised: altitude, speed, heading habit, trajectory, antenna, physics, shadowing, "
        "time offset)",
    )
    s.add_argument(
        "--logs",
        action="store_true",
        help="with --suite: write the flights as CSV logs + suite.json "
        "(the benchmark cache for rfsl evaluate --suite-dir) instead of feature chunks",
    )
    s.add_argument(
        "--family",
        default="afar",
        metavar="FAMILY",
        help="with --suite: physics family: a built-in one (mission.workshop.suite.FAMILIES: afar, "
        "generic, afar-heavy), the shipped afar-fades (issue 34's family: fades, rough "
        "shadowing) or a physics family file F.json (rfsl gap --family; "
        "mission/data/afar_family.json), which draws each flight's physics, shadowing, noise and "
        "offset; a .json implies --suite unseen",
    )
    s.add_argument(
        "--center",
        default="afar",
        metavar="PRESET",
        help="with --suite --family afar: the preset at the family's centre (afar, "
        "afar:fit328, ...)",
    )


def add_randomisation_arguments(p: argparse.ArgumentParser) -> None:
    """The domain-randomisation options, each off unless given (--randomise: the recommended
    set)."""
    g = p.add_argument_group("domain randomisation (each off unless given)")
    g.add_argument(
        "--randomise",
        action="store_true",
        help="recommended set: altitude 20,47; offset -30,30; all generators with random "
        "parameters; "
        "truncate 0.5,1; patterns dipole,measured with random heading; beta 0,3; eps-r 2,20; "
        f"tx height {DEFAULT_TX_HEIGHT_M:g},5; noise 1,3 dB",
    )
    g.add_argument("--altitude", type=_range, help="cruise altitude range LO,HI metres")
    g.add_argument("--offset", type=_range, help="constant RSS offset range LO,HI dB")
    g.add_argument(
        "--trajectories",
        help="comma list of trajectory generators drawn per flight (e.g. spiral,lawnmower: the "
        "names of a mission's trajectory.generator; an unknown one is refused with the list)",
    )
    g.add_argument(
        "--random-params", action="store_true", help="random generator parameters per flight"
    )
    g.add_argument("--truncate", type=_range, help="kept fraction of the cruise LO,HI (e.g. 0.5,1)")
    g.add_argument(
        "--patterns", help="comma list of antenna patterns drawn per flight (dipole, measured)"
    )
    g.add_argument(
        "--random-heading", action="store_true", help="random mounting heading of measured patterns"
    )
    g.add_argument("--beta", type=_range, help="leg-shadowing exponent range LO,HI")
    g.add_argument("--eps-r", type=_range, help="ground relative permittivity range LO,HI")
    g.add_argument("--tx-height", type=_range, help="transmitter height range LO,HI metres")
    g.add_argument("--noise", type=_range, help="RSS noise standard deviation range LO,HI dB")
    g.add_argument(
        "--fixed-heading",
        type=float,
        metavar="P",
        help="probability that a flight holds one random compass heading instead of yawing "
        "along the "
        "track (AFAR 2023 vehicles held a near-constant heading)",
    )
    g.add_argument("--speed", type=_range, help="cruise speed range LO,HI m/s")
    g.add_argument(
        "--shadowing",
        type=_range,
        help="std range LO,HI dB of a spatially correlated shadowing field",
    )
    g.add_argument(
        "--shadowing-corr", type=_range, help="its correlation distance range LO,HI m (default 30)"
    )
    g.add_argument(
        "--drag-pitch",
        type=_range,
        metavar="LO,HI",
        help="steady nose-down pitch per m/s of airspeed, range LO,HI deg per m/s (default 0.6: "
        "-3 deg at 5.5 m/s, as AFAR flew; ArduCopter SITL cruises near 2.8, PX4 SITL near 5.6)",
    )
    g.add_argument(
        "--physics-heading-jitter",
        type=float,
        metavar="DEG",
        help="with --physics: jitter the preset's UAV-antenna heading by U(-DEG, DEG) per flight",
    )


def randomisation_from_args(args: argparse.Namespace):
    """The ``Randomisation`` the flags ask for (``--randomise`` first, single flags override it)."""
    from mission.trajectory.generators import GENERATORS
    from mission.workshop.dataset import Randomisation

    d: dict = {}
    if args.randomise:
        d = {
            "altitude_m": (20.0, 47.0),
            "offset_db": (-30.0, 30.0),
            "trajectories": tuple(GENERATORS),
            "random_params": True,
            "truncate": (0.5, 1.0),
            "patterns": ("dipole", "measured"),
            "random_heading": True,
            "beta": (0.0, 3.0),
            "eps_r": (2.0, 20.0),
            "tx_height_m": (DEFAULT_TX_HEIGHT_M, 5.0),  # AFAR rover to the paper's 5 m
            "noise_db": (1.0, 3.0),
        }
    for flag, key in (
        ("altitude", "altitude_m"),
        ("offset", "offset_db"),
        ("truncate", "truncate"),
        ("beta", "beta"),
        ("eps_r", "eps_r"),
        ("tx_height", "tx_height_m"),
        ("noise", "noise_db"),
        ("speed", "speed_mps"),
        ("shadowing", "shadowing_db"),
        ("shadowing_corr", "shadowing_corr_m"),
        ("fixed_heading", "fixed_heading"),
        ("physics_heading_jitter", "physics_heading_jitter_deg"),
        ("drag_pitch", "drag_pitch_deg_per_mps"),
    ):
        v = getattr(args, flag)
        if v is not None:
            d[key] = v
    if args.trajectories:
        d["trajectories"] = tuple(t.strip() for t in args.trajectories.split(",") if t.strip())
    if args.patterns:
        d["patterns"] = tuple(t.strip() for t in args.patterns.split(",") if t.strip())
    if args.random_params:
        d["random_params"] = True
    if args.random_heading:
        d["random_heading"] = True
    return Randomisation(**d)


def run(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    from mission.workshop.dataset import DatasetConfig, check_config, generate_dataset

    console = Console()
    check_args(args)
    if args.logs:
        from mission.workshop.suite import BENCHMARK_SEED

        args.seed = BENCHMARK_SEED if args.seed is None else args.seed
        return _write_logs(args, console)
    args.seed = 0 if args.seed is None else args.seed
    cfg = DatasetConfig(
        mission=args.mission,
        n=args.n,
        model=args.model,
        seed=args.seed,
        chunk=args.chunk,
        features=tuple(f.strip() for f in args.features.split(",") if f.strip()),
        randomisation=randomisation_from_args(args),
        physics=args.physics,
        feature_config={"arc_step_m": args.arc_step} if args.arc_step else {},
        suite=args.suite,
        suite_family=args.family,
        suite_center=args.center,
    )
    check_config(cfg)
    with Progress(
        TextColumn("[bold]dataset"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("flights"),
        TimeRemainingColumn(),
        console=console,
    ) as prog:
        task = prog.add_task("flights", total=args.n)
        m = generate_dataset(
            cfg,
            args.out,
            workers=args.workers,
            progress=lambda done, total: prog.update(task, completed=done),
            overwrite=args.overwrite,
        )
    g = m["generation"]
    console.print(
        f"{m['n']} flights ({cfg.physics_label}, seed {args.seed}) in {g['seconds']:.1f} s "
        f"= {g['flights_per_s']:.2f} flights/s on {args.workers} worker(s); "
        f"{len(m['chunks'])} chunk(s) in {args.out}"
    )
    return 0


def check_args(args: argparse.Namespace) -> None:
    """Refuse bad options before anything is written (``InputError`` naming the option); a
    family file implies ``--suite unseen``."""
    from mission.errors import InputError
    from mission.trajectory.generators import GENERATORS

    for t in (args.trajectories or "").split(","):
        if t.strip() and t.strip() not in GENERATORS:
            raise InputError(
                f"unknown generator {t.strip()!r} (expected {', '.join(GENERATORS)})",
                field="--trajectories",
            )
    from mission.defaults import MAX_WORKERS

    if not 1 <= args.workers <= MAX_WORKERS:
        raise InputError(f"must be 1..{MAX_WORKERS}, got {args.workers}", field="--workers")
    if args.n > MAX_FLIGHTS:  # a billion flights ran until killed for memory
        raise InputError(
            f"must be <= {MAX_FLIGHTS:,} flights (split a larger set over seeds), got {args.n:,}",
            field="--n",
        )
    if not 1 <= args.chunk <= MAX_FLIGHTS:
        raise InputError(f"must be 1..{MAX_FLIGHTS:,}, got {args.chunk}", field="--chunk")
    # physical ranges that cannot be negative (numpy raised "scale < 0")
    for flag in (
        "altitude",
        "tx_height",
        "noise",
        "shadowing",
        "shadowing_corr",
        "speed",
        "beta",
        "eps_r",
        "truncate",
    ):
        r = getattr(args, flag, None)
        if r is not None and r[0] < 0:
            raise InputError(
                f"must not be negative, got {r[0]:g},{r[1]:g}", field="--" + flag.replace("_", "-")
            )
    from pathlib import Path

    from mission.cli.main import out_parent_ok

    out_parent_ok(Path(args.out), folder=True)
    if args.family.lower().endswith(".json") and not args.suite:
        args.suite = "unseen"  # a family file draws benchmark-style flights
    if args.family != "afar" and not args.suite:
        raise InputError(
            "--family draws benchmark-style flights: add --suite unseen", field="--family"
        )
    if args.suite:
        from mission.workshop.suite import resolve_family

        resolve_family(args.family)  # a bad family file is refused before anything is written
    if args.suite and args.mission:
        raise InputError(
            "--suite flights fly the AFAR field with their own paths: give no mission",
            field="mission",
        )
    if not args.suite and not args.mission:
        raise InputError("give a mission YAML (or --suite unseen)", field="mission")
    if args.logs and not args.suite:
        raise InputError("--logs writes benchmark flights: needs --suite unseen", field="--logs")


def _write_logs(args: argparse.Namespace, console) -> int:
    """``--suite unseen --logs``: the benchmark's flights as CSV logs (the cache ``rfsl evaluate``
    reads)."""
    import time
    from pathlib import Path

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    from mission.errors import InputError
    from mission.workshop.suite_cache import write_suite

    out = Path(args.out)
    if (out / "suite.json").exists() and not args.overwrite:
        raise InputError("a suite exists already here (use --overwrite)", source=str(out))
    t0 = time.perf_counter()
    with Progress(
        TextColumn("[bold]suite logs"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=console,
    ) as prog:
        task = prog.add_task("flights", total=args.n)
        write_suite(
            out,
            args.n,
            args.seed,
            args.family,
            args.center,
            args.workers,
            progress=lambda d, _t: prog.update(task, completed=d),
        )
    console.print(
        f"{args.n} benchmark flights (seed {args.seed}, family {args.family}) in "
        f"{time.perf_counter() - t0:.1f} s -> {out}"
    )
    return 0
