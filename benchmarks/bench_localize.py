"""Benchmark: the default ``localize`` on ~20 000-sample flights, after start-up (wall and CPU
seconds).

What is timed, per flight, ``--repeat`` times (median, min, max): ``localize_log(path)`` with no
method, i.e. the real-log default ``fusion`` (self-calibrating grid +
``models/rfsl_spiral_e2r.onnx``), from reading the CSV to the estimate with its uncertainty regions;
then its parts (CSV read + sample selection, the self-calibrating grid, the network: features +
inference).  Wall seconds (``perf_counter``) and this process's CPU seconds (``process_time``: all
its threads) are both printed with the load average, so a figure taken on a shared machine can be
judged.  Target: wall < 1 s per flight.

Start-up, timed once and printed separately: importing the package and its numerical libraries,
creating the onnxruntime session, and the first (warm-up) call.  The default path creates its
session on every call (a few ms, included in the per-flight figure).

Flights: the six real AFAR flights of ``../shared/data/afar2023/mat`` (20 500-22 000 rows each;
imported into a temporary folder), else / also (``--sim``) a simulated spiral flight of
``--samples`` samples written as a real receiver's log.  ``--threads N`` sets ``RFSL_THREADS``
(k-means and onnxruntime threads; default 1, 0 = the libraries' own choice, i.e. no limit).

    python benchmarks/bench_localize.py [--flights all|N] [--sim] [--samples 20000] [--repeat 5] \
        [--threads 1]
    # the evidence stage
    python benchmarks/bench_localize.py --method evidence --flights 2 --repeat 3
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
AFAR_MAT = REPO.parent / "shared" / "data" / "afar2023" / "mat"


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t0: tuple[float, float]) -> tuple[float, float]:
    t1 = _clock()
    return t1[0] - t0[0], t1[1] - t0[1]


def _fmt(samples: list[tuple[float, float]]) -> str:
    w = [s[0] for s in samples]
    c = [s[1] for s in samples]
    return (
        f"wall median {statistics.median(w):.3f} s (min {min(w):.3f}, max {max(w):.3f}), "
        f"CPU median {statistics.median(c):.3f} s"
    )


def _load() -> str:
    return (
        "load average "
        + " ".join(f"{v:.2f}" for v in os.getloadavg())
        + f" on {os.cpu_count()} cores"
    )


def simulated_log(folder: Path, n: int, seed: int = 0) -> Path:
    """A spiral flight of the default mission, repeated to ``n`` samples, written as a real
    receiver's log."""
    import numpy as np

    from mission.defaults import DEFAULT_TX_HEIGHT_M
    from mission.flightlog import make_meta, write_flight_log
    from mission.physics import make_model
    from mission.simulate import simulate_flight
    from mission.spec import load_mission

    spec = load_mission(REPO / "missions" / "spiral.yaml")
    tx = np.array([120.0, 180.0, DEFAULT_TX_HEIGHT_M])
    fl = simulate_flight(
        spec.waypoints_enu(), tx, make_model("e2r"), spec.sim_config(), np.random.default_rng(seed)
    )
    cols = fl.log_columns(spec.field.origin)
    reps = int(np.ceil(n / len(cols["t_s"])))
    cols = {k: np.tile(v, reps)[:n] for k, v in cols.items()}
    cols["t_s"] = np.arange(n) * 0.03
    return write_flight_log(
        folder / f"sim_{n}.csv", cols, make_meta(spec.field.origin, {"kind": "real"})
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--flights", default="all", help="'all' six real flights, or how many of them (0: none)"
    )
    ap.add_argument(
        "--sim",
        action="store_true",
        help="also a simulated flight (always when ../shared is absent)",
    )
    ap.add_argument("--samples", type=int, default=20000, help="samples of the simulated flight")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--threads",
        type=int,
        default=None,
        help="RFSL_THREADS for this run (default: as set, else 1)",
    )
    ap.add_argument(
        "--parts", action="store_true", help="also time the parts (read, selfcal, network)"
    )
    ap.add_argument(
        "--method", default=None, help="time this method instead of the default (e.g. evidence)"
    )
    args = ap.parse_args()
    if args.threads is not None:
        os.environ["RFSL_THREADS"] = str(args.threads)
    print(
        f"python {sys.version.split()[0]}; "
        f"RFSL_THREADS={os.environ.get('RFSL_THREADS', '(unset: 1)')}; {_load()}"
    )

    t0 = _clock()
    import numpy  # noqa: F401
    import onnxruntime  # noqa: F401
    import scipy.ndimage  # noqa: F401
    import sklearn.cluster  # noqa: F401

    from mission.localize.api import fusion_model_path, localize_log
    from mission.localize.onnx_model import OnnxLocalizer
    from mission.localize.selfcal import SelfCalibratingGrid

    t_import = _since(t0)
    t0 = _clock()
    net = OnnxLocalizer(fusion_model_path())
    t_session = _since(t0)

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        logs: list[tuple[str, Path]] = []
        mats = sorted(AFAR_MAT.glob("results_useful_ori_exp_*_loc_*.mat"))
        take = len(mats) if args.flights == "all" else int(args.flights)
        if mats and take > 0:
            from mission.importers.afar import AFAR2023_TRUTH, import_afar_mat

            for f in mats[:take]:
                loc = int(f.stem.rsplit("_", 1)[1])
                logs.append(
                    (
                        f.stem.replace("results_useful_ori_exp_", "afar "),
                        import_afar_mat(f, d, truth=AFAR2023_TRUTH[loc]).out_path,
                    )
                )
        if args.sim or not logs:
            logs.append((f"sim {args.samples}", simulated_log(d, args.samples)))

        t0 = _clock()
        # warm-up: first k-means, first pattern tables, lazy imports
        localize_log(logs[0][1], method=args.method)
        t_warm = _since(t0)
        print(
            f"start-up (once): imports {t_import[0]:.2f} s wall / {t_import[1]:.2f} s CPU; "
            "onnxruntime session "
            f"{1e3 * t_session[0]:.1f} ms; first localize_log (warm-up) {t_warm[0]:.2f} s wall / "
            f"{t_warm[1]:.2f} s CPU"
        )
        what = (
            f"localize_log --method {args.method}"
            if args.method
            else "default localize_log (fusion)"
        )
        print(f"{what} per flight, {args.repeat} repeats after start-up; target wall < 1 s")
        allw: list[tuple[float, float]] = []
        for name, path in logs:
            runs = []
            for _ in range(args.repeat):
                t0 = _clock()
                est = localize_log(path, method=args.method)
                runs.append(_since(t0))
            allw += runs
            print(
                f"  {name:10s} {est.selection.used:6d}/{est.selection.total:6d} samples "
                f"({est.method}): {_fmt(runs)}"
            )
            if args.parts:
                from mission.flightlog import read_flight_log
                from mission.localize.preprocess import select_samples

                parts: dict[str, list[tuple[float, float]]] = {
                    "read+select": [],
                    "selfcal": [],
                    "network": [],
                    "session": [],
                }
                for _ in range(args.repeat):
                    t0 = _clock()
                    log = read_flight_log(path)
                    part, _ = select_samples(log)
                    parts["read+select"].append(_since(t0))
                    from mission.localize.api import search_area

                    sc = SelfCalibratingGrid(area=search_area(log))
                    t0 = _clock()
                    sc.predict(part)
                    parts["selfcal"].append(_since(t0))
                    t0 = _clock()
                    net.predict(part)
                    parts["network"].append(_since(t0))
                    t0 = _clock()
                    OnnxLocalizer(fusion_model_path())
                    parts["session"].append(_since(t0))
                for k, v in parts.items():
                    print(f"      {k:12s} {_fmt(v)}")
        print(f"all flights: {_fmt(allw)}; {_load()}")


if __name__ == "__main__":
    main()
