"""The paper's comparison table on one call: localizers x test data, mean / median / 90th-percentile
error.

Localizers: ONNX networks (each labelled by the propagation model of its training data and its
feature kind, read from the model's metadata) and the classical estimators of
``mission.localize.classical`` (``strongest``, ``centroid``, ``grid`` = model-based
maximum-likelihood grid search).

Test data:

- simulated test sets written by ``rfsl dataset`` (one per trajectory, or any): networks run on the
  stored features in one batch; the classical methods need the per-sample flight, which is
  *regenerated* from the manifest (flight ``i`` is a deterministic function of the dataset seed and
  ``i``), on the first ``n_classical`` flights only (the grid search is the slow one);
- real flights: flight logs with the truth in their sidecar, run through ``localize_log`` exactly as
  the ``localize`` CLI does (cruise selection, frame conversion).  ``import_afar`` converts the AFAR
  MAT files with the truth table of ``../shared/data/README.md``.

Errors are horizontal (2D) distances in metres.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.files import write_text
from mission.flightlog import read_flight_log
from mission.importers.afar import (
    AFAR2023_SUSPECT,
    AFAR2023_SUSPECT_NOTE,
    AFAR2023_TRUTH,
    import_afar_mat,
)
from mission.localize.api import localize_log, make_localizer
from mission.localize.methods import METHOD_NAMES, names_where
from mission.localize.onnx_model import OnnxLocalizer
from mission.physics.presets import load_preset
from mission.physics.propagation import MODEL_NAMES
from mission.spec import MissionSpec
from mission.workshop.dataset import (
    FlightSimulator,
    dataset_config,
    dataset_heights,
    load_dataset,
    physics_label,
    read_manifest,
)

# strongest, centroid, grid: run on simulated test sets as well
CLASSICAL = names_where(kind="classical")
GRID_PHYSICS = MODEL_NAMES  # the grid accepts every propagation model make_model builds


def parse_method(spec: str) -> tuple[str, dict]:
    """A classical method spec -> (method, grid keyword arguments).

    ``strongest``, ``centroid``, ``grid`` (the grid's default physics: e2r on simulated tests, as
    before), ``grid:free-space`` / ``grid:two-ray`` / ``grid:e2r`` (that propagation model, default
    antennas) and ``grid:preset:NAME`` (a calibrated physics preset, e.g. ``grid:preset:afar``).
    """
    name, _, physics = spec.partition(":")
    if name not in CLASSICAL or (physics and name != "grid"):
        raise InputError(
            f"unknown method {spec!r} (expected {', '.join(CLASSICAL)}, grid:MODEL or "
            "grid:preset:NAME)",
            field="--methods",
        )
    if not physics:
        return name, {}
    if physics.startswith("preset:"):
        # unknown preset: InputError now, not mid-evaluation
        load_preset(physics.removeprefix("preset:"))
        return name, {"preset": physics.removeprefix("preset:")}
    if physics not in GRID_PHYSICS:
        raise InputError(
            f"unknown grid physics {physics!r} (expected {', '.join(GRID_PHYSICS)} or preset:NAME)",
            field="--methods",
        )
    return name, {"model": physics}


SUITE_METHODS = (
    "default",
    "strongest",
    "centroid",
    "grid",
    "grid:MODEL",
    "grid:preset:NAME",
    "onnx:PATH",
)


def suite_method(spec: str) -> dict:
    """A benchmark method spec -> ``localize_log`` keyword arguments (everything a real log would
    get).

    ``default`` (``localize``'s own choice for a real log), ``strongest``, ``centroid``, ``grid``
    (the real-log grid: ``afar`` preset), ``grid:MODEL`` / ``grid:preset:NAME``, ``onnx:PATH`` (a
    network), or any other method name of the registry (``mission.localize.methods``), run with its
    defaults.
    """
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
        return (
            {"method": method, "physics_model": kw["model"]}
            if "model" in kw
            else {"method": method}
        )
    if spec in METHOD_NAMES:
        return {"method": spec}
    raise InputError(
        f"unknown method {spec!r} (expected {', '.join(SUITE_METHODS)} or one of "
        f"{', '.join(METHOD_NAMES)})",
        field="--methods",
    )


def grid_physics(kw: dict, grid_params: dict) -> tuple[str | None, dict | None, str | None]:
    """(physics model, its parameters, physics preset) for a parsed method's ``kw``: a preset
    replaces the model and its parameters; otherwise the method's model, else ``grid_params``'
    (default e2r)."""
    if "preset" in kw:
        return None, None, kw["preset"]
    return kw.get("model", grid_params.get("model", "e2r")), grid_params.get("params"), None


# Rover truth by AFAR location number (../shared/data/README.md; antenna about 1.5 m above ground).
AFAR_TRUTH = AFAR2023_TRUTH


@dataclass
class Row:
    """One cell group of the table: a localizer on one test set."""

    test: str
    method: str
    train_model: str | None
    features: str | None
    errors: list[float]
    names: list[str] = field(default_factory=list)
    # region level ("50", "90") -> truth inside
    covered: dict[str, list[bool]] = field(default_factory=dict)

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
            d.update(
                mean_m=float(e.mean()),
                median_m=float(np.median(e)),
                p90_m=float(np.percentile(e, 90)),
            )
        for lvl, c in sorted(self.covered.items()):
            if c:
                d[f"coverage_{lvl}"] = float(np.mean(c))
                d[f"n_regions_{lvl}"] = len(c)
        if self.names:
            d["per_flight_m"] = {n: float(v) for n, v in zip(self.names, self.errors, strict=True)}
        return d


def model_label(path: str | Path) -> tuple[str, str, str]:
    """(label, training propagation model, feature kind) of an ONNX model from its metadata."""
    loc = OnnxLocalizer(path)
    td = loc.meta.get("training_data") or {}
    models = sorted(
        {d.get("model") for d in td.get("datasets", []) if isinstance(d, dict)} - {None}
    )
    tm = "+".join(models) if models else "?"
    return f"net:{Path(path).stem}", tm, loc.kind


def _errors(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(pred[:, 0] - truth[:, 0], pred[:, 1] - truth[:, 1])


def test_label(manifest: dict) -> str:
    """'sim:<model>:<trajectory>@<altitude>' of a test dataset."""
    cfg = manifest["config"]
    r = cfg.get("randomisation", {})
    traj = "+".join(r.get("trajectories") or [manifest.get("mission_generator", "?")])
    alt = r.get("altitude_m")
    alt_s = (
        f"{alt[0]:g}-{alt[1]:g}m"
        if alt
        else f"{manifest.get('mission_altitude_m', MissionSpec.altitude_m):g}m"
    )
    return f"sim:{physics_label(cfg)}:{traj}@{alt_s}"


def evaluate_sim(
    models: Sequence[str | Path],
    dataset: str | Path,
    classical: Sequence[str] = CLASSICAL,
    n_classical: int = 100,
    grid_params: dict | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Row]:
    """Networks on all flights of a simulated test set; classical methods on its first
    ``n_classical``."""
    m = read_manifest(dataset, need=("chunks", "config", "feature_config", "field_origin"))
    label = test_label(m)
    rows: list[Row] = []
    cache: dict[str, np.ndarray] = {}
    truth = heights = None
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
            arrays, _ = load_dataset(dataset, (loc.kind, "tx_enu", "params"))
            cache[loc.kind] = arrays[loc.kind]
            truth = arrays["tx_enu"]
            heights = dataset_heights(arrays["params"])
        pred = np.concatenate(
            [
                loc.predict_features(cache[loc.kind][i : i + 2048], heights[i : i + 2048])
                for i in range(0, len(cache[loc.kind]), 2048)
            ]
        )
        name, tm, kind = model_label(mp)
        rows.append(Row(label, name, tm, kind, _errors(pred, truth).tolist()))
        if progress:
            progress(f"{label}: {name} done")
    if classical and n_classical > 0:
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
            fs = sim.draw(i).samples
            for c, loc in locs.items():
                est = loc.predict(fs)
                errs[c].append(float(np.hypot(est.x_m - fs.tx_enu_m[0], est.y_m - fs.tx_enu_m[1])))
            if progress:
                progress(f"{label}: classical {i + 1}/{n}")
        for c in classical:
            rows.append(Row(f"{label}[:{n}]", c, None, "classical", errs[c]))
    return rows


def afar_truth(path: str | Path) -> tuple[tuple[float, float] | None, str | None]:
    """Truth (lat, lon) and a caveat for an AFAR MAT/log file named
    ``..._exp_<team>_loc_<n>...``."""
    mm = re.search(r"exp_(\d+)_loc_(\d+)", Path(path).name)
    if not mm:
        return None, None
    team, loc = mm.group(1), int(mm.group(2))
    return AFAR_TRUTH.get(loc), AFAR2023_SUSPECT_NOTE if (
        int(team),
        loc,
    ) == AFAR2023_SUSPECT else None


def import_afar(mat_dir: str | Path, out_dir: str | Path) -> list[Path]:
    """Import every ``*.mat`` AFAR file in ``mat_dir`` into flight logs (truth from the table) in
    ``out_dir``."""
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
                tx_height_m=gp.get("tx_height_m", DEFAULT_TX_HEIGHT_M),
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

    write_text(path, json.dumps(rep, indent=1), "--out")
    return rep


# ------------------------------------------------------------------------------ unseen-flight
# benchmark
