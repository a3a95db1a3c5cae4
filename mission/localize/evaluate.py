"""The paper's comparison table on one call: localizers x test data, mean / median / 90th-percentile error.

Localizers: ONNX networks (each labelled by the propagation model of its training data and its feature
kind, read from the model's metadata) and the classical estimators of ``mission.localize.classical``
(``strongest``, ``centroid``, ``grid`` = model-based maximum-likelihood grid search).

Test data:

- simulated test sets written by ``rfsl dataset`` (one per trajectory, or any): networks run on the
  stored features in one batch; the classical methods need the per-sample flight, which is *regenerated*
  from the manifest (flight ``i`` is a deterministic function of the dataset seed and ``i``), on the first
  ``n_classical`` flights only (the grid search is the slow one);
- real flights: flight logs with the truth in their sidecar, run through ``localize_log`` exactly as the
  ``localize`` CLI does (cruise selection, frame conversion).  ``import_afar`` converts the AFAR MAT files
  with the truth table of ``../shared/data/README.md``.

Errors are horizontal (2D) distances in metres.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.importers.afar import AFAR2023_TRUTH

CLASSICAL = ("strongest", "centroid", "grid")
GRID_PHYSICS = ("free-space", "two-ray", "e2r")


def parse_method(spec: str) -> tuple[str, dict]:
    """A classical method spec -> (method, grid keyword arguments).

    ``strongest``, ``centroid``, ``grid`` (the grid's default physics: e2r on simulated tests, as before),
    ``grid:free-space`` / ``grid:two-ray`` / ``grid:e2r`` (that propagation model, default antennas) and
    ``grid:preset:NAME`` (a calibrated physics preset, e.g. ``grid:preset:afar``).
    """
    name, _, physics = spec.partition(":")
    if name not in CLASSICAL or (physics and name != "grid"):
        raise InputError(f"unknown method {spec!r} (expected {', '.join(CLASSICAL)}, grid:MODEL or "
                         "grid:preset:NAME)", field="--methods")
    if not physics:
        return name, {}
    if physics.startswith("preset:"):
        from mission.physics.presets import load_preset

        load_preset(physics.removeprefix("preset:"))  # unknown preset: InputError now, not mid-evaluation
        return name, {"preset": physics.removeprefix("preset:")}
    if physics not in GRID_PHYSICS:
        raise InputError(f"unknown grid physics {physics!r} (expected {', '.join(GRID_PHYSICS)} or preset:NAME)",
                         field="--methods")
    return name, {"model": physics}


def grid_physics(kw: dict, grid_params: dict) -> tuple[str | None, dict | None, str | None]:
    """(physics model, its parameters, physics preset) for a parsed method's ``kw``: a preset replaces the
    model and its parameters; otherwise the method's model, else ``grid_params``' (default e2r)."""
    if "preset" in kw:
        return None, None, kw["preset"]
    return kw.get("model", grid_params.get("model", "e2r")), grid_params.get("params"), None

# Rover truth by AFAR location number (../shared/data/README.md; antenna about 1.5 m above ground).
AFAR_TRUTH = AFAR2023_TRUTH
AFAR_SUSPECT = {
    ("288", 3): "team 288 location 3 is suspect: strongest RSS about 147 m from the labelled point"
}


@dataclass
class Row:
    """One cell group of the table: a localizer on one test set."""

    test: str
    method: str
    train_model: str | None
    features: str | None
    errors: list[float]
    names: list[str] = field(default_factory=list)
    covered: dict[str, list[bool]] = field(default_factory=dict)  # region level ("50", "90") -> truth inside

    def summary(self) -> dict:
        e = np.asarray(self.errors, dtype=float)
        d = {
            "test": self.test,
            "method": self.method,
            "train_model": self.train_model,
            "features": self.features,
            "n": int(e.size),
        }
        if e.size:
            d.update(mean_m=float(e.mean()), median_m=float(np.median(e)), p90_m=float(np.percentile(e, 90)))
        for lvl, c in sorted(self.covered.items()):
            if c:
                d[f"coverage_{lvl}"] = float(np.mean(c))
                d[f"n_regions_{lvl}"] = len(c)
        if self.names:
            d["per_flight_m"] = {n: float(v) for n, v in zip(self.names, self.errors, strict=True)}
        return d


def model_label(path: str | Path) -> tuple[str, str, str]:
    """(label, training propagation model, feature kind) of an ONNX model from its metadata."""
    from mission.localize.onnx_model import OnnxLocalizer

    loc = OnnxLocalizer(path)
    td = loc.meta.get("training_data") or {}
    models = sorted({d.get("model") for d in td.get("datasets", []) if isinstance(d, dict)} - {None})
    tm = "+".join(models) if models else "?"
    return f"net:{Path(path).stem}", tm, loc.kind


def _errors(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(pred[:, 0] - truth[:, 0], pred[:, 1] - truth[:, 1])


def test_label(manifest: dict) -> str:
    """'sim:<model>:<trajectory>@<altitude>' of a test dataset."""
    from mission.localize.dataset import physics_label

    cfg = manifest["config"]
    r = cfg.get("randomisation", {})
    traj = "+".join(r.get("trajectories") or [manifest.get("mission_generator", "?")])
    alt = r.get("altitude_m")
    alt_s = f"{alt[0]:g}-{alt[1]:g}m" if alt else f"{manifest.get('mission_altitude_m', 30):g}m"
    return f"sim:{physics_label(cfg)}:{traj}@{alt_s}"


def evaluate_sim(
    models: Sequence[str | Path],
    dataset: str | Path,
    classical: Sequence[str] = CLASSICAL,
    n_classical: int = 100,
    grid_params: dict | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Row]:
    """Networks on all flights of a simulated test set; classical methods on its first ``n_classical``."""
    from mission.localize.dataset import FlightSimulator, dataset_config, load_dataset, read_manifest
    from mission.localize.onnx_model import OnnxLocalizer

    m = read_manifest(dataset)
    label = test_label(m)
    rows: list[Row] = []
    cache: dict[str, np.ndarray] = {}
    truth = None
    for mp in models:
        loc = OnnxLocalizer(mp)
        key = loc.cfg.mismatch(m["feature_config"])
        if key is not None:
            raise InputError(
                f"model's feature configuration differs from the test set's ({key})", source=str(mp)
            )
        if loc.origin.to_dict() != m["field_origin"]:
            raise InputError("model's field origin differs from the test set's", source=str(mp))
        if loc.kind not in cache:
            arrays, _ = load_dataset(dataset, (loc.kind, "tx_enu"))
            cache[loc.kind] = arrays[loc.kind]
            truth = arrays["tx_enu"]
        pred = np.concatenate(
            [
                loc.predict_features(cache[loc.kind][i : i + 2048])
                for i in range(0, len(cache[loc.kind]), 2048)
            ]
        )
        name, tm, kind = model_label(mp)
        rows.append(Row(label, name, tm, kind, _errors(pred, truth).tolist()))
        if progress:
            progress(f"{label}: {name} done")
    if classical and n_classical > 0:
        from mission.localize.api import make_localizer

        cfg = dataset_config(m)
        sim = FlightSimulator(cfg)
        n = min(n_classical, cfg.n)
        gp = grid_params or {}
        locs = {}
        for c in classical:
            method, kw = parse_method(c)
            model, params, preset = grid_physics(kw, gp)
            locs[c] = make_localizer(
                method,
                physics_model=model or "e2r",  # unused when a preset is given
                physics_params=params,
                tx_height_m=gp.get("tx_height_m", sim.spec.source.tx_height_m),
                area=sim.spec.field.rover_area,
                physics_preset=preset,
            )
        errs: dict[str, list[float]] = {c: [] for c in classical}
        for i in range(n):
            fd = sim.draw(i)
            for c, loc in locs.items():
                est = loc.predict((fd.enu, fd.rss_dbm, fd.attitude_rad))
                errs[c].append(float(np.hypot(est.x_m - fd.tx_enu[0], est.y_m - fd.tx_enu[1])))
            if progress:
                progress(f"{label}: classical {i + 1}/{n}")
        for c in classical:
            rows.append(Row(f"{label}[:{n}]", c, None, "classical", errs[c]))
    return rows


def afar_truth(path: str | Path) -> tuple[tuple[float, float] | None, str | None]:
    """Truth (lat, lon) and a caveat for an AFAR MAT/log file named ``..._exp_<team>_loc_<n>...``."""
    mm = re.search(r"exp_(\d+)_loc_(\d+)", Path(path).name)
    if not mm:
        return None, None
    team, loc = mm.group(1), int(mm.group(2))
    return AFAR_TRUTH.get(loc), AFAR_SUSPECT.get((team, loc))


def import_afar(mat_dir: str | Path, out_dir: str | Path) -> list[Path]:
    """Import every ``*.mat`` AFAR file in ``mat_dir`` into flight logs (truth from the table) in ``out_dir``."""
    from mission.importers.afar import import_afar_mat

    out = []
    for f in sorted(Path(mat_dir).glob("*.mat")):
        truth, _ = afar_truth(f)
        res = import_afar_mat(f, out_dir, truth=truth, overwrite=True)
        out.append(Path(res.out_path))
    if not out:
        raise InputError("no .mat files found", source=str(mat_dir))
    return out


def evaluate_real(
    models: Sequence[str | Path],
    logs: Sequence[str | Path],
    classical: Sequence[str] = CLASSICAL,
    grid_params: dict | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Row]:
    """Every localizer on every real log (truth from the sidecar), through ``localize_log``."""
    from mission.flightlog import read_flight_log
    from mission.localize.api import localize_log

    gp = grid_params or {}
    methods: list[tuple[str, str | None, str | None, str | None, str | Path | None]] = []
    for mp in models:
        name, tm, kind = model_label(mp)
        methods.append((name, tm, kind, "onnx", mp))
    for c in classical:
        methods.append((c, None, "classical", c, None))
    rows = {name: Row("real", name, tm, kind, [], []) for name, tm, kind, _, _ in methods}
    for lp in logs:
        log = read_flight_log(lp)
        if log.truth_enu is None:
            raise InputError("real log has no truth in its sidecar", source=str(lp))
        for name, _tm, _kind, spec, mp in methods:
            method, kw = parse_method(spec) if spec != "onnx" else ("onnx", {})
            model, params, preset = grid_physics(kw, gp)
            est = localize_log(
                log,
                method=method,
                model_path=mp,
                physics_model=model,
                physics_params=params,
                tx_height_m=gp.get("tx_height_m", 1.5),
                physics_preset=preset,
            )
            rows[name].errors.append(float(est.error_m))
            rows[name].names.append(Path(lp).stem)
        if progress:
            progress(f"real: {Path(lp).stem} done")
    return list(rows.values())


def write_report(rows: Sequence[Row], path: str | Path, extra: dict | None = None) -> dict:
    """The JSON report: one summary per row, plus ``extra`` (commands, notes)."""
    rep = {"rows": [r.summary() for r in rows]}
    if extra:
        rep.update(extra)
    Path(path).write_text(json.dumps(rep, indent=1))
    return rep


# ------------------------------------------------------------------------------ unseen-flight benchmark

SUITE_METHODS = ("default", "strongest", "centroid", "grid", "grid:MODEL", "grid:preset:NAME", "onnx:PATH")


def suite_method(spec: str) -> dict:
    """A benchmark method spec -> ``localize_log`` keyword arguments (everything a real log would get).

    ``default`` (``localize``'s own choice for a real log), ``strongest``, ``centroid``, ``grid`` (the real-log
    grid: ``afar`` preset), ``grid:MODEL`` / ``grid:preset:NAME``, ``onnx:PATH`` (a network), or any other
    method name ``mission.localize.api`` knows (``METHOD_NAMES``), run with its defaults.
    """
    from mission.localize.api import METHOD_NAMES

    spec = spec.strip()
    if spec == "default":
        return {}
    if spec.startswith("onnx:"):
        path = spec.removeprefix("onnx:")
        if not Path(path).is_file():
            raise InputError("no such model file", source=path, field="--methods")
        return {"method": "onnx", "model_path": path}
    name = spec.partition(":")[0]
    if name in CLASSICAL:
        method, kw = parse_method(spec)
        if "preset" in kw:
            return {"method": method, "physics_preset": kw["preset"]}
        return {"method": method, "physics_model": kw["model"]} if "model" in kw else {"method": method}
    if spec in METHOD_NAMES:
        return {"method": spec}
    raise InputError(f"unknown method {spec!r} (expected {', '.join(SUITE_METHODS)} or one of "
                     f"{', '.join(METHOD_NAMES)})", field="--methods")


def _level(key, region: dict) -> str | None:
    lv = region.get("level", key)
    try:
        v = float(lv)
    except (TypeError, ValueError):
        return None
    return f"{round(v * 100 if v <= 1 else v):d}"


def region_contains(region: dict, xy) -> bool:
    """Whether point ``xy`` (log ENU m) lies in an uncertainty region of ``est.extras["regions"]``.

    Accepted shapes: ``{"polygon": [[x, y], ...]}`` (also ``polygon_xy_m``), or an ellipse
    ``{"center_m": [x, y], "semi_axes_m": [a, b], "angle_deg": t}`` with the first semi-axis ``t`` degrees
    counter-clockwise from east (``center``/``center_xy_m``, ``axes_m``/``semi_axes`` and ``angle`` also read),
    or ``{"center_m": [x, y], "cov_m2": [[..], [..]], "chi2": k}`` = the set ``d^T cov^-1 d <= k``.
    """
    p = np.asarray(xy, dtype=float)[:2]
    poly = region.get("polygon", region.get("polygon_xy_m"))
    if poly is not None:
        from matplotlib.path import Path as MPath

        return bool(MPath(np.asarray(poly, dtype=float)).contains_point(p))
    c = np.asarray(next(region[k] for k in ("center_m", "center_xy_m", "center") if k in region), dtype=float)
    d = p - c[:2]
    if "cov_m2" in region or "cov" in region:
        cov = np.asarray(region.get("cov_m2", region.get("cov")), dtype=float)
        return bool(d @ np.linalg.solve(cov, d) <= float(region.get("chi2", 1.0)))
    a, b = (float(v) for v in next(region[k] for k in ("semi_axes_m", "axes_m", "semi_axes") if k in region))
    t = math.radians(float(region.get("angle_deg", region.get("angle", 0.0))))
    u = d[0] * math.cos(t) + d[1] * math.sin(t)
    v = -d[0] * math.sin(t) + d[1] * math.cos(t)
    return bool((u / max(a, 1e-9)) ** 2 + (v / max(b, 1e-9)) ** 2 <= 1.0)


def _regions(est) -> dict[str, dict]:
    """Level ("50", "90") -> region of an estimate (dict keyed by level or list of dicts with "level")."""
    regs = (est.extras or {}).get("regions")
    if not regs:
        return {}
    items = regs.items() if isinstance(regs, dict) else ((None, r) for r in regs)
    out = {}
    for k, r in items:
        if isinstance(r, dict) and (lvl := _level(k, r)) is not None:
            out[lvl] = r
    return out


def _coverage(est, truth) -> dict[str, bool]:
    """Level -> whether the truth lies in the estimate's region: on the posterior grid when the estimate has
    one (``mission.localize.uncertainty.region_covers``), else by the region's drawn shape."""
    from mission.localize.uncertainty import region_covers

    out = {}
    for lvl, r in _regions(est).items():
        c = region_covers(est, float(truth[0]), float(truth[1]), float(r["level"])) if "level" in r else None
        out[lvl] = region_contains(r, truth) if c is None else c
    return out


_SUITE: dict = {}


def _suite_init(methods: dict[str, dict], source: dict, one_thread: bool = False) -> None:
    if one_thread:  # worker processes: one BLAS/OpenMP thread each (k-means threads spin on a busy machine)
        import sklearn.cluster  # noqa: F401  (load its OpenMP runtime so that the limit applies to it)
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    _SUITE.clear()
    _SUITE.update(methods=methods, source=source)
    if "dir" in source:
        from mission.localize.suite import read_suite

        _SUITE["cached"] = read_suite(source["dir"])


def _suite_flight(i: int) -> dict:
    """Every method on flight ``i``: {label: [error m, {level: covered}, seconds]}."""
    import time

    from mission.localize.api import localize_log

    src = _SUITE["source"]
    if "cached" in _SUITE:
        log, truth, _ = _SUITE["cached"].load(i)
    else:
        from mission.localize.suite import unseen_flight

        log, truth, _ = unseen_flight(src["seed"], i, src["family"], src["center"])
    out = {}
    for label, kw in _SUITE["methods"].items():
        t0 = time.perf_counter()
        est = localize_log(log, **kw)
        dt = time.perf_counter() - t0
        cov = _coverage(est, truth)
        out[label] = [float(np.hypot(est.x_m - truth[0], est.y_m - truth[1])), cov, dt]
    return out


def evaluate_suite(
    methods: Sequence[str],
    n: int = 200,
    seed: int | None = None,
    suite_dir: str | Path | None = None,
    family: str = "afar",
    center: str = "afar",
    workers: int = 2,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[list[Row], dict[str, float]]:
    """Methods on the unseen-flight benchmark (``mission.localize.suite``): (rows, mean seconds per flight).

    Flights come from ``suite_dir`` (a cache written by ``write_suite``; its first ``n``) or are simulated
    here from ``seed`` (default ``BENCHMARK_SEED``).  Each method sees only the log (``localize_log``); the
    error is 2D against the truth kept beside it; when an estimate carries ``extras["regions"]`` the rows
    count how often the truth lies in the 50 % / 90 % region.  Results do not depend on ``workers``.
    """
    from mission.localize.suite import BENCHMARK_SEED, read_suite

    labels = {m: suite_method(m) for m in methods}
    if not labels:
        raise InputError("no methods to evaluate", field="--methods")
    if suite_dir is not None:
        cs = read_suite(suite_dir)
        n = min(n, len(cs)) if n else len(cs)
        mf = cs.manifest
        source: dict = {"dir": str(suite_dir)}
        test = f"suite:unseen[seed={mf['seed']},family={mf['family']},n={n}]"
    else:
        seed = BENCHMARK_SEED if seed is None else seed
        source = {"seed": int(seed), "family": family, "center": center}
        test = f"suite:unseen[seed={seed},family={family},n={n}]"
    rows = {m: Row(test, m, None, "onnx" if kw.get("method") == "onnx" else "classical", [], [])
            for m, kw in labels.items()}
    secs = {m: 0.0 for m in labels}
    if workers <= 1:
        _suite_init(labels, source)
        results = map(_suite_flight, range(n))
        pool = None
    else:
        import multiprocessing as mp

        ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
        pool = ctx.Pool(workers, initializer=_suite_init, initargs=(labels, source, True))
        results = pool.imap(_suite_flight, range(n), chunksize=1)
    try:
        for i, res in enumerate(results):
            for m, (err, cov, dt) in res.items():
                rows[m].errors.append(err)
                rows[m].names.append(f"flight_{i:05d}")
                for lvl, c in cov.items():
                    rows[m].covered.setdefault(lvl, []).append(c)
                secs[m] += dt
            if progress:
                progress(i + 1, n)
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    return list(rows.values()), {m: s / max(n, 1) for m, s in secs.items()}


def suite_draws(n: int, seed: int | None = None, suite_dir: str | Path | None = None, family: str = "afar",
                center: str = "afar") -> list[dict]:
    """The draws (every parameter) of benchmark flights 0..n-1, from a cache or redrawn (cheap: no flying)."""
    from mission.localize.suite import BENCHMARK_SEED, draw_flight, read_suite

    if suite_dir is not None:
        return [f["draw"] for f in read_suite(suite_dir).manifest["flights"][:n]]
    s = BENCHMARK_SEED if seed is None else seed
    return [draw_flight(s, i, family, center)[0] for i in range(n)]


def _axis_value(draw: dict, axis: str):
    v: object = draw
    for part in axis.split("."):  # e.g. physics.rx_antenna, trajectory_params.region
        if not isinstance(v, dict) or part not in v:
            raise InputError(f"benchmark draws have no axis {axis!r} (e.g. heading_habit, tx_outside_flight_area, "
                             "altitude_m, physics.rx_antenna, trajectory)", field="--by")
        v = v[part]
    return v


def breakdown(rows: Sequence[Row], draws: Sequence[dict], axis: str, bins: int = 3) -> dict[str, dict[str, float]]:
    """Mean error per method by the value of one draw axis: {group label: {method: mean m, "n": count}}.

    Text / bool axes group by value; numeric axes by ``bins`` equal-count bins (label ``lo-hi``)."""
    vals = [_axis_value(d, axis) for d in draws]
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in vals):
        x = np.asarray(vals, dtype=float)
        edges = np.quantile(x, np.linspace(0, 1, bins + 1))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
        labels = [f"{edges[k]:.3g}-{edges[k + 1]:.3g}" for k in range(bins)]
        keys = [labels[k] for k in idx]
    else:
        keys = [str(v) for v in vals]
    out: dict[str, dict[str, float]] = {}
    for g in dict.fromkeys(sorted(set(keys))):
        m = np.array([k == g for k in keys])
        out[g] = {"n": int(m.sum())}
        for r in rows:
            e = np.asarray(r.errors, dtype=float)[: len(m)]
            out[g][r.method] = float(e[m[: e.size]].mean())
    return out
