"""Calibrate and check the error circles of estimates without a posterior
(``mission/localize/error_circles.py``).

Calibration (``--write`` stores it: networks in their card ``models/<name>.json`` key ``regions``,
the classical methods in ``mission/data/method_circles.json``):

- ``sim``: a network on ``--sim-n`` simulated flights (seed ``--sim-seed``, never trained on) of the
  domain where ``localize`` uses it on simulated logs (``SIM_DOMAINS``): the spiral networks on
  their spirals, ``rfsl_default`` on every other generator at 20-47 m (its training altitudes),
  ``rfsl_afar`` on its AFAR-physics check domain; a classical method on ``rfsl simulate`` logs of
  the five generator missions (``--method-seeds``);
- ``real``: the unseen-flight benchmark caches given by ``--calib-dirs`` (seeds 2027 and 2028 of the
  reality-fitted family ``mission/data/afar_family.json``, the output of ``rfsl gap --family`` on
  the six real flights).

Check (held out, ``--check-dir`` and ``--mat``): coverage on the benchmark seed 2026 and on the six
real AFAR flights, and on simulated logs of the product path (``--product-seeds``:
``benchmarks/sim_default.py``'s sets, ``localize``'s default and each classical method on ``rfsl
simulate`` logs).

    # and 2028, 2026
    rfsl dataset --suite unseen --logs --family mission/data/afar_family.json --n 200 --seed 2027 \\
        --out /tmp/suite_2027
    # 'real' only
    python benchmarks/calibrate_error_circles.py --calib-dirs /tmp/suite_2027 /tmp/suite_2028 \\
        --sim-n 0 --method-seeds 0:0 --write
    # 1 min
    python benchmarks/calibrate_error_circles.py --sim-n 0 --method-seeds 0:0 \\
        --check-dir /tmp/suite_2026 --mat ../shared/data/afar2023/mat --product-seeds 7000:7040
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from mission.evidence import conformal_quantile
from mission.localize.api import localize_log
from mission.localize.card import model_digest
from mission.localize.error_circles import CIRCLE_METHODS, LEVELS, METHOD_CIRCLES, REGIONS_KEY
from mission.localize.onnx_model import OnnxLocalizer
from mission.threads import limit_worker
from mission.workshop.dataset import DatasetConfig, dataset_heights, generate_dataset, load_dataset
from mission.workshop.evaluate import import_afar
from mission.workshop.evaluate_suite import region_coverage
from mission.workshop.suite_cache import read_suite

sys.path.insert(0, str(Path(__file__).resolve().parent))  # sim_default's sets
from sim_default import SETS, mission_variant, simulate_log

REPO = Path(__file__).resolve().parent.parent


def calibration_record(
    errors, source: str, model_path: str | Path | None = None, levels: tuple[float, ...] = LEVELS
) -> dict:
    """What is stored for one domain: radii per level, the number of flights, where they came from
    and, for a network, the digest of the model file they were measured on."""
    e = np.asarray(errors, dtype=float)
    radii = {f"{lv:g}": round(conformal_quantile(e, lv), 2) for lv in levels}
    if not all(math.isfinite(r) for r in radii.values()):
        raise ValueError(
            f"{e.size} flights cannot calibrate levels {levels}: need at least "
            f"{math.ceil(max(levels) / (1 - max(levels)) - 1e-9)}"
        )
    rec = {
        "radii_m": radii,
        "n": int(e.size),
        "mean_error_m": round(float(e.mean()), 2),
        "calibrated_on": source,
    }
    if model_path is not None:
        rec["model_sha256"] = model_digest(model_path)
    return rec


MODELS = (
    "rfsl_spiral_e2r",
    "rfsl_spiral_alt",
    "rfsl_default",
    "rfsl_afar",
    "rfsl_spiral_e2r_ens5",
)  # rfsl_spiral_tilt: calibrated (--models rfsl_spiral_tilt --sim-seed 3200), refused by its rule
GENERATOR_MISSIONS = ("spiral", "lawnmower", "edge_sweep", "expanding_square", "random_waypoints")
OTHER_GENERATORS = GENERATOR_MISSIONS[1:]
# network -> (how its sim domain differs from its card's CI check set, description)
SIM_DOMAINS = {
    "rfsl_spiral_e2r": ({}, "simulated spirals at 30 m, e2r, dipoles"),
    "rfsl_spiral_e2r_ens5": ({}, "simulated spirals at 30 m, e2r, dipoles"),
    "rfsl_spiral_alt": ({}, "simulated spirals at 15-60 m, e2r, dipoles"),
    "rfsl_spiral_tilt": (
        {},
        "simulated spirals at 30 m, e2r, dipoles, flown nose down (0.6-6 deg of pitch per m/s)",
    ),
    "rfsl_default": (
        {"altitude_m": (20.0, 47.0), "trajectories": OTHER_GENERATORS, "random_params": True},
        "simulated lawnmower / edge sweep / expanding square / random waypoints at 20-47 m, e2r",
    ),
    "rfsl_afar": ({}, "simulated AFAR-physics flights (its CI check domain)"),
}


def kwargs_of(name: str) -> dict:
    """``localize_log`` keywords for a shipped network's name or a classical method's."""
    return (
        {"method": name}
        if name in CIRCLE_METHODS
        else {"model_path": str(REPO / "models" / f"{name}.onnx")}
    )


def sim_errors(name: str, n: int, seed: int) -> tuple[np.ndarray, str]:
    """2D errors (m) of network ``name`` on ``n`` fresh simulated flights of its sim domain."""
    rec = json.loads((REPO / "models" / f"{name}.json").read_text())["ci_check"]
    cfg = DatasetConfig.from_dict(rec["dataset_config"])
    change, what = SIM_DOMAINS[name]
    cfg = replace(
        cfg,
        n=n,
        seed=seed,
        chunk=max(n, 1),
        mission=str(REPO / cfg.mission),
        randomisation=replace(cfg.randomisation, **change),
    )
    loc = OnnxLocalizer(REPO / "models" / f"{name}.onnx")
    with tempfile.TemporaryDirectory() as tmp:
        generate_dataset(cfg, Path(tmp) / "ds", workers=2)
        arrays, _ = load_dataset(Path(tmp) / "ds", (loc.kind, "tx_enu", "params"))
    pred = loc.predict_features(arrays[loc.kind], dataset_heights(arrays["params"]))
    return np.hypot(*(pred - arrays["tx_enu"][:, :2]).T), f"{what}; {n} flights, seed {seed}"


def _run(est, truth) -> tuple[float, dict, str, float]:
    """(error m, {level: covered}, answered by, the 90 % region's area over its circle's: < 1 where
    clipped)."""
    reg = est.outer_region
    share = (
        reg.area_m2 / (np.pi * reg.radius_m**2)
        if reg is not None and reg.radius_m is not None
        else float("nan")
    )
    return (
        float(np.hypot(est.x_m - truth[0], est.y_m - truth[1])),
        region_coverage(est, truth),
        Path(est.extras.get("model_path", est.method)).name,
        float(share),
    )


def _suite_flight(job: tuple[dict, str, int]) -> tuple[float, dict, str, float]:
    """(error m, {level: covered}, answered by) on flight i of a benchmark cache."""
    kw, suite_dir, i = job
    log, truth, _ = read_suite(suite_dir).load(i)
    return _run(localize_log(log, **kw), truth)


def _simulated_flight(job: tuple[dict, str, str, int]) -> tuple[float, dict, str, float]:
    """(error, coverage, answered by) on one ``rfsl simulate`` log of a mission (``kw`` {} = the
    default)."""
    kw, mission, out, seed = job
    est = localize_log(simulate_log(mission, out, seed), **kw)
    return _run(est, (est.extras["truth_x_m"], est.extras["truth_y_m"]))


def _pool(fn, jobs: list) -> list:
    with ProcessPoolExecutor(2, initializer=limit_worker) as ex:
        return list(ex.map(fn, jobs, chunksize=4))


def suite_runs(name: str, dirs: list[str]) -> list[tuple[float, dict, str, float]]:
    """Per-flight runs of ``name`` over the flights of benchmark caches ``dirs``."""
    return _pool(
        _suite_flight, [(kwargs_of(name), d, i) for d in dirs for i in range(len(read_suite(d)))]
    )


def simulated_runs(
    kw: dict, missions: list[str], seeds: range
) -> list[tuple[float, dict, str, float]]:
    """Per-flight runs on ``rfsl simulate`` logs of each mission file for each seed."""
    with tempfile.TemporaryDirectory() as tmp:
        return _pool(_simulated_flight, [(kw, m, tmp, s) for m in missions for s in seeds])


def real_runs(name: str, mat: str) -> list[tuple[float, dict, str, float]]:
    """Per-flight runs of ``name`` on the six real AFAR flights."""
    with tempfile.TemporaryDirectory() as tmp:
        ests = [localize_log(p, **kwargs_of(name)) for p in import_afar(mat, tmp)]
    return [_run(e, (e.extras["truth_x_m"], e.extras["truth_y_m"])) for e in ests]


def coverage_line(runs: list[tuple[float, dict, str, float]]) -> str:
    """'mean m, truth in 50 % / 90 %, the 90 % region's mean share of its circle' over per-flight
    runs."""
    e = np.array([r[0] for r in runs])
    cov = {lv: np.mean([r[1].get(lv, False) for r in runs]) for lv in ("50", "90")}
    by = ", ".join(sorted({r[2] for r in runs}))
    share = (
        np.nanmean([r[3] for r in runs]) if any(np.isfinite(r[3]) for r in runs) else float("nan")
    )
    return (
        f"mean {e.mean():.1f} m, in 50 % / 90 %: {100 * cov['50']:.1f} / {100 * cov['90']:.1f} "
        "%, 90 % region "
        f"{100 * share:.0f} % of its circle after clipping to the rover area (n={len(e)}; {by})"
    )


def product_check(seeds: str, methods: list[str]) -> None:
    """Coverage on simulated logs of the product path (``sim_default.SETS``): the default and each
    method."""
    lo, hi = (int(v) for v in seeds.split(":"))
    with tempfile.TemporaryDirectory() as tmp:
        for label, mission, alt in SETS:
            mission = mission_variant(str(REPO / mission), tmp, label, alt)
            for kw in [{}] + [{"method": m} for m in methods]:
                runs = simulated_runs(kw, [mission], range(lo, hi))
                print(
                    f"product path, {label}, {kw.get('method', 'default')}: {coverage_line(runs)}",
                    flush=True,
                )


def benchmark_label(dirs: list[str]) -> str:
    """'unseen-flight benchmark, FAMILY family (seeds ...)' for the caches ``dirs`` (the family
    their manifests name: a built-in name, or a family file's name and sha256 prefix)."""
    fams = sorted({str(read_suite(d).manifest.get("family", "afar")) for d in dirs})
    seeds = ", ".join(str(read_suite(d).manifest.get("seed")) for d in dirs)
    return f"unseen-flight benchmark, {' + '.join(fams)} family (seeds {seeds})"


def store(name: str, regions: dict) -> None:
    """Write a calibration: a network's into its card, a classical method's into
    method_circles.json."""
    path = METHOD_CIRCLES if name in CIRCLE_METHODS else REPO / "models" / f"{name}.json"
    d = json.loads(path.read_text()) if path.is_file() else {}
    key = name if name in CIRCLE_METHODS else REGIONS_KEY
    d[key] = {**d.get(key, {}), **regions}
    path.write_text(json.dumps(d, indent=1) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--models",
        nargs="+",
        default=list(MODELS) + list(CIRCLE_METHODS),
        help="networks and methods",
    )
    ap.add_argument(
        "--sim-n", type=int, default=1000, help="networks: simulated calibration flights (0: none)"
    )
    ap.add_argument("--sim-seed", type=int, default=3100)
    ap.add_argument(
        "--method-seeds", default="3100:3160", help="methods: rfsl simulate seeds per mission"
    )
    ap.add_argument(
        "--calib-dirs", nargs="*", default=[], help="benchmark caches for the 'real' calibration"
    )
    ap.add_argument("--check-dir", help="a held-out benchmark cache (seed 2026)")
    ap.add_argument("--mat", help="../shared/data/afar2023/mat: coverage on the six real flights")
    ap.add_argument(
        "--product-seeds", help="first:last: coverage on simulated logs of the product path"
    )
    ap.add_argument("--write", action="store_true", help="store the calibrations")
    args = ap.parse_args()

    lo, hi = (int(v) for v in args.method_seeds.split(":"))
    for name in args.models:
        regions, model = {}, None if name in CIRCLE_METHODS else REPO / "models" / f"{name}.onnx"
        if model is not None and args.sim_n > 0:
            err, src = sim_errors(name, args.sim_n, args.sim_seed)
            regions["sim"] = calibration_record(err, src, model)
        elif model is None and hi > lo:
            missions = [str(REPO / "missions" / f"{m}.yaml") for m in GENERATOR_MISSIONS]
            runs = simulated_runs(kwargs_of(name), missions, range(lo, hi))
            regions["sim"] = calibration_record(
                [r[0] for r in runs],
                f"rfsl simulate logs of missions/"
                f"{{{','.join(GENERATOR_MISSIONS)}}}.yaml, seeds {lo}-{hi - 1}",
            )
        if args.calib_dirs:
            runs = suite_runs(name, args.calib_dirs)
            regions["real"] = calibration_record(
                [r[0] for r in runs],
                f"{benchmark_label(args.calib_dirs)}; {len(runs)} flights",
                model,
            )
        print(name, json.dumps(regions), flush=True)
        if args.write and regions:
            store(name, regions)
        if args.check_dir:
            print(
                f"  held-out benchmark {Path(args.check_dir).name}: "
                f"{coverage_line(suite_runs(name, [args.check_dir]))}",
                flush=True,
            )
        if args.mat:
            print(f"  six real flights: {coverage_line(real_runs(name, args.mat))}", flush=True)
    if args.product_seeds:
        product_check(args.product_seeds, [m for m in args.models if m in CIRCLE_METHODS])


if __name__ == "__main__":
    main()
