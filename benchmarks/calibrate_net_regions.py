"""Calibrate and check the shipped networks' error circles (``mission/localize/net_regions.py``).

Calibration (``--write`` stores it in each card, ``models/<name>.json`` key ``regions``):

- ``sim``: ``--sim-n`` simulated flights (seed ``--sim-seed``, never trained on) of the domain where ``localize``
  uses the network on simulated logs (``SIM_DOMAINS``): the spiral networks on their spirals, ``rfsl_default``
  on every other generator at 20-47 m (its training altitudes), ``rfsl_afar`` on its AFAR-physics check domain;
- ``real``: the unseen-flight benchmark caches given by ``--calib-dirs`` (``afar`` family, seeds 2027 and 2028).

Check (held out, ``--check-dir`` and ``--mat``): coverage of the circles on the benchmark seed 2026 and on the six
real AFAR flights, and on the product path of simulated logs (``--product-seeds``: ``benchmarks/sim_default.py``'s
sets, ``localize``'s default network on ``rfsl simulate`` logs).

    rfsl dataset --suite unseen --logs --n 200 --seed 2027 --out /tmp/suite_2027      # and 2028, 2026
    python benchmarks/calibrate_net_regions.py --calib-dirs /tmp/suite_2027 /tmp/suite_2028 \\
        --check-dir /tmp/suite_2026 --mat ../shared/data/afar2023/mat --product-seeds 7000:7040 --write  # ~3 min
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))  # sim_default's sets
MODELS = ("rfsl_spiral_e2r", "rfsl_spiral_alt", "rfsl_default", "rfsl_afar", "rfsl_spiral_e2r_ens5")
OTHER_GENERATORS = ("lawnmower", "edge_sweep", "expanding_square", "random_waypoints")
# network -> (how its sim domain differs from its card's CI check set, description)
SIM_DOMAINS = {
    "rfsl_spiral_e2r": ({}, "simulated spirals at 30 m, e2r, dipoles"),
    "rfsl_spiral_e2r_ens5": ({}, "simulated spirals at 30 m, e2r, dipoles"),
    "rfsl_spiral_alt": ({}, "simulated spirals at 15-60 m, e2r, dipoles"),
    "rfsl_default": ({"altitude_m": (20.0, 47.0), "trajectories": OTHER_GENERATORS, "random_params": True},
                     "simulated lawnmower / edge sweep / expanding square / random waypoints at 20-47 m, e2r"),
    "rfsl_afar": ({}, "simulated AFAR-physics flights (its CI check domain)"),
}


def sim_errors(name: str, n: int, seed: int) -> tuple[np.ndarray, str]:
    """2D errors (m) of network ``name`` on ``n`` fresh simulated flights of its sim domain."""
    from mission.localize.altitude_scale import dataset_heights
    from mission.localize.dataset import DatasetConfig, generate_dataset, load_dataset
    from mission.localize.onnx_model import OnnxLocalizer

    rec = json.loads((REPO / "models" / f"{name}.json").read_text())["ci_check"]
    cfg = DatasetConfig.from_dict(rec["dataset_config"])
    change, what = SIM_DOMAINS[name]
    cfg = replace(cfg, n=n, seed=seed, chunk=max(n, 1), mission=str(REPO / cfg.mission),
                  randomisation=replace(cfg.randomisation, **change))
    loc = OnnxLocalizer(REPO / "models" / f"{name}.onnx")
    with tempfile.TemporaryDirectory() as tmp:
        generate_dataset(cfg, Path(tmp) / "ds", workers=2)
        arrays, _ = load_dataset(Path(tmp) / "ds", (loc.kind, "tx_enu", "params"))
    pred = loc.predict_features(arrays[loc.kind], dataset_heights(arrays["params"]))
    return np.hypot(*(pred - arrays["tx_enu"][:, :2]).T), f"{what}; {n} flights, seed {seed}"


def _log_errors(job: tuple[str, str, int]) -> tuple[float, dict]:
    """(error m, {level: covered}) of a network alone on flight i of a benchmark cache."""
    from mission.localize.api import localize_log
    from mission.localize.evaluate_suite import _coverage
    from mission.localize.suite_cache import read_suite

    model, suite_dir, i = job
    log, truth, _ = read_suite(suite_dir).load(i)
    est = localize_log(log, model_path=model)
    return float(np.hypot(est.x_m - truth[0], est.y_m - truth[1])), _coverage(est, truth)


def suite_runs(name: str, dirs: list[str]) -> list[tuple[float, dict]]:
    """Per-flight (error, coverage) of network ``name`` over the flights of benchmark caches ``dirs``."""
    from mission.localize.features import one_thread_process
    from mission.localize.suite_cache import read_suite

    model = str(REPO / "models" / f"{name}.onnx")
    jobs = [(model, d, i) for d in dirs for i in range(len(read_suite(d)))]
    with ProcessPoolExecutor(2, initializer=one_thread_process) as ex:
        return list(ex.map(_log_errors, jobs, chunksize=8))


def real_runs(name: str, mat: str) -> list[tuple[float, dict]]:
    """Per-flight (error, coverage) of network ``name`` alone on the six real AFAR flights."""
    from mission.localize.api import localize_log
    from mission.localize.evaluate import import_afar
    from mission.localize.evaluate_suite import _coverage

    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for p in import_afar(mat, tmp):
            est = localize_log(p, model_path=REPO / "models" / f"{name}.onnx")
            out.append((est.error_m, _coverage(est, (est.extras["truth_x_m"], est.extras["truth_y_m"]))))
    return out


def _product_flight(job: tuple[str, str, int]) -> tuple[float, dict, str]:
    """(error, coverage, network) of ``localize``'s default on one ``rfsl simulate`` log of a mission."""
    import contextlib
    import os

    from mission.cli.main import main as rfsl
    from mission.localize.api import localize_log
    from mission.localize.evaluate_suite import _coverage

    mission, out, seed = job
    d = Path(out) / f"s{seed}"
    with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
        rfsl(["simulate", mission, "--seed", str(seed), "--out", str(d)])
    est = localize_log(next(d.glob("*.csv")))
    truth = (est.extras["truth_x_m"], est.extras["truth_y_m"])
    return est.error_m, _coverage(est, truth), Path(est.extras.get("model_path", "?")).name


def product_runs(seeds: str) -> None:
    """Coverage of the default's circles on simulated logs of the product path (``sim_default.SETS``)."""
    import yaml
    from sim_default import SETS

    from mission.localize.features import one_thread_process

    lo, hi = (int(v) for v in seeds.split(":"))
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(2, initializer=one_thread_process) as ex:
        for label, mission, alt in SETS:
            if alt is not None:
                spec = yaml.safe_load((REPO / mission).read_text())
                spec["altitude_m"], spec["name"] = alt, f"{Path(mission).stem}_{alt:.0f}m"
                mission = str(Path(tmp) / f"{spec['name']}.yaml")
                Path(mission).write_text(yaml.safe_dump(spec))
            out = tempfile.mkdtemp(dir=tmp)
            runs = list(ex.map(_product_flight, [(str(REPO / mission), out, s) for s in range(lo, hi)]))
            nets = sorted({r[2] for r in runs})
            print(f"product path, {label} ({', '.join(nets)}): {coverage_line(runs)}", flush=True)


def coverage_line(runs: list[tuple[float, dict]]) -> str:
    """'mean m, truth in 50 % / 90 %' over per-flight runs."""
    e = np.array([r[0] for r in runs])
    cov = {lv: np.mean([r[1].get(lv, False) for r in runs]) for lv in ("50", "90")}
    return f"mean {e.mean():.1f} m, in 50 % / 90 %: {100 * cov['50']:.1f} / {100 * cov['90']:.1f} % (n={len(e)})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", nargs="+", default=list(MODELS))
    ap.add_argument("--sim-n", type=int, default=1000)
    ap.add_argument("--sim-seed", type=int, default=3100)
    ap.add_argument("--calib-dirs", nargs="*", default=[], help="benchmark caches for the 'real' calibration")
    ap.add_argument("--check-dir", help="a held-out benchmark cache (seed 2026)")
    ap.add_argument("--mat", help="../shared/data/afar2023/mat: coverage on the six real flights")
    ap.add_argument("--write", action="store_true", help="store the calibration in each model card")
    ap.add_argument("--product-seeds", help="first:last: coverage on simulated logs of the product path")
    args = ap.parse_args()
    from mission.localize.net_regions import REGIONS_KEY, calibration_record

    for name in args.models:
        card, model = REPO / "models" / f"{name}.json", REPO / "models" / f"{name}.onnx"
        regions = {}
        if args.sim_n > 0:
            err, src = sim_errors(name, args.sim_n, args.sim_seed)
            regions["sim"] = calibration_record(err, src, model)
        if args.calib_dirs:
            runs = suite_runs(name, args.calib_dirs)
            seeds = ", ".join(Path(d).name for d in args.calib_dirs)
            regions["real"] = calibration_record([r[0] for r in runs], f"unseen-flight benchmark, afar family "
                                                 f"({seeds}); {len(runs)} flights", model)
        print(name, json.dumps(regions), flush=True)
        if args.write and regions:
            d = json.loads(card.read_text())
            d[REGIONS_KEY] = {**d.get(REGIONS_KEY, {}), **regions}
            card.write_text(json.dumps(d, indent=1) + "\n")
        if args.check_dir:
            print(f"  held-out benchmark {Path(args.check_dir).name}: "
                  f"{coverage_line(suite_runs(name, [args.check_dir]))}", flush=True)
        if args.mat:
            print(f"  six real flights: {coverage_line(real_runs(name, args.mat))}", flush=True)
    if args.product_seeds:
        product_runs(args.product_seeds)


if __name__ == "__main__":
    main()
