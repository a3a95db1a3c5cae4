"""The whole diagnosis of one set of flights: the gap, where it lies, which effect, how far it
shrinks.

Why one function: the CLI, the self-test, the real-flight benchmark and the tests all need the same
sequence (alignment -> gap of the reference models -> residual breakdown with block-bootstrap flags
-> candidate ranking and greedy ladder on held-out data -> localization cost per rung), and a single
``Diagnosis`` object is what the report renders.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from mission.gap.align import SEGMENTS, Alignment, align
from mission.gap.candidate import Candidate
from mission.gap.describe import describe_params
from mission.gap.fit import FitConfig, _map, _pooled, make_folds, offset_residual
from mission.gap.ladder import Rung, ladder
from mission.gap.pipeline import LocalizationModel, Pipeline, shifted_geometry
from mission.gap.power import power_statement
from mission.gap.spatial import usable_candidates
from mission.gap.stats import BinnedResidual, binned_residual, block_length, ecdf, summarize
from mission.gap.structure import footprint, residual_structure
from mission.gap.temporal import time_power_statement
from mission.localize.classical import ModelGridSearch
from mission.physics import make_model
from mission.physics.propagation import MODEL_NAMES
from mission.samples import FlightSamples

REFERENCE_MODELS = MODEL_NAMES  # every named model is a reference

BREAKDOWN_EDGES: dict[str, np.ndarray] = {
    "distance_m": np.array([0, 25, 50, 75, 100, 150, 200, 250, 300, 400, 600], dtype=float),
    "depression_deg": np.arange(-20.0, 91.0, 10.0),
    "body_azimuth_deg": np.arange(0.0, 361.0, 30.0),
    "world_azimuth_deg": np.arange(0.0, 361.0, 30.0),
    "attitude_deg": np.array([0, 2, 4, 6, 8, 10, 15, 20, 45], dtype=float),
}


def base_pipeline(name: str = "e2r", pattern: str = "dipole", **params: Any) -> Pipeline:
    """A pipeline from a reference model name (``make_model``) and an antenna pattern for both
    ends."""
    return Pipeline(make_model(name, pattern=pattern, **params))


@dataclass
class ModelGap:
    """In-sample gap of one model (per-flight offset, optional slope), per flight and pooled."""

    name: str
    per_flight: dict[str, dict[str, float]]
    pooled: dict[str, float]
    cdf_x: np.ndarray
    cdf_q: np.ndarray
    residuals: list[np.ndarray] = field(default_factory=list, repr=False)


@dataclass
class Diagnosis:
    """Everything the report shows."""

    flights: list[FlightSamples]
    alignments: list[Alignment]
    base_label: str
    gaps: list[ModelGap]
    breakdown: list[BinnedResidual]
    field_map: dict[str, Any]
    rungs: list[Rung]
    localization: list[dict[str, Any]]
    block_lens: list[int]
    config: dict[str, Any]
    # residual structure: "base" and "final" rungs
    structure: dict[str, Any] = field(default_factory=dict)
    # per added rung: size (dB) and where it acts
    footprints: dict[str, Any] = field(default_factory=dict)
    # what the data can show below the UAV (nadir.py)
    near_nadir: dict[str, Any] = field(default_factory=dict)
    # what the data can show along time (temporal.py)
    time_power: dict[str, Any] = field(default_factory=dict)
    # rung label -> ground- or body-fixed test (frame.py)
    frames: dict[str, Any] = field(default_factory=dict)


def model_gap(
    pipe: Pipeline, flights: Sequence[FlightSamples], cfg: FitConfig, name: str
) -> ModelGap:
    """Gap of ``pipe`` on all samples with the free constants fitted per flight."""
    res = []
    per = {}
    for f in flights:
        r = offset_residual(f.rss_dbm, pipe.predict(f), cfg.slope, "l2")
        res.append(r)
        per[f.name] = summarize(r).as_dict()
    pooled = np.concatenate(res)
    x, q = ecdf(pooled)
    return ModelGap(name, per, summarize(pooled).as_dict(), x, q, res)


def residual_breakdown(
    al: Sequence[Alignment],
    res: Sequence[np.ndarray],
    block_lens: Sequence[int],
    rng: np.random.Generator,
    n_boot: int = 300,
) -> list[BinnedResidual]:
    """Residual by distance, depression, body/world azimuth, attitude and flight segment, with
    flagged bins."""
    out = []
    for var, edges in BREAKDOWN_EDGES.items():
        xs = [a.as_dict()[var] for a in al]
        out.append(binned_residual(var, xs, res, edges, block_lens, rng, n_boot))
    segments = [a.segment.astype(float) for a in al]
    b = binned_residual(
        "segment",
        segments,
        res,
        np.arange(len(SEGMENTS), dtype=float),
        block_lens,
        rng,
        n_boot,
        categorical=True,
    )
    out.append(b)
    return out


def field_map(
    al: Sequence[Alignment],
    res: Sequence[np.ndarray],
    block_lens: Sequence[int],
    rng: np.random.Generator,
    cell_m: float = 20.0,
    n_boot: int = 200,
) -> dict[str, Any]:
    """Mean residual on a grid of ``cell_m`` cells over the field, with block-bootstrap flags per
    cell."""
    x = np.concatenate([a.x for a in al])
    y = np.concatenate([a.y for a in al])
    x0, y0 = np.floor(x.min() / cell_m) * cell_m, np.floor(y.min() / cell_m) * cell_m
    nx = int(np.ceil((x.max() - x0) / cell_m)) + 1
    ny = int(np.ceil((y.max() - y0) / cell_m)) + 1
    cells = [
        ((np.floor((a.y - y0) / cell_m)) * nx + np.floor((a.x - x0) / cell_m)).astype(float)
        for a in al
    ]
    b = binned_residual(
        "cell",
        cells,
        res,
        np.arange(nx * ny, dtype=float),
        block_lens,
        rng,
        n_boot,
        min_count=20,
        categorical=True,
    )
    return {
        "x0": float(x0),
        "y0": float(y0),
        "cell_m": cell_m,
        "nx": nx,
        "ny": ny,
        "mean_db": b.mean.reshape(ny, nx),
        "count": b.count.reshape(ny, nx),
        "flagged": b.flagged.reshape(ny, nx),
    }


def localization_cost(
    rungs: Sequence[Rung],
    flights: Sequence[FlightSamples],
    area: Any = None,
    step_m: float = 10.0,
    max_points: int = 1500,
    split: str = "blocks",
) -> list[dict[str, Any]]:
    """Model-based grid-search error per rung and flight
    (``mission.localize.classical.ModelGridSearch``).

    With ``split="flights"`` flight k is localized with the rung fitted without it (fold k):
    held-out localization; otherwise with the first fold's fit.
    """
    out = []
    for rung in rungs:
        row: dict[str, Any] = {"rung": rung.label, "errors_m": {}}
        for k, f in enumerate(flights):
            # make_folds' deal
            pipe = rung.pipes[k % len(rung.pipes)] if split == "flights" else rung.pipes[0]
            rx, att = (
                (f.enu_m, f.attitude_rad)
                if pipe.time_offset_s == 0
                else shifted_geometry(f, f.t_s - pipe.time_offset_s)
            )
            est = ModelGridSearch(
                LocalizationModel(pipe, rung.label),
                tx_height_m=float(f.tx_enu_m[2]),
                area=area,
                step_m=step_m,
                max_points=max_points,
                loss="l2" if area is None else "soft_l1",
            )
            e = est.predict(FlightSamples(enu_m=rx, rss_dbm=f.rss_dbm, attitude_rad=att))
            row["errors_m"][f.name] = float(np.hypot(e.x_m - f.tx_enu_m[0], e.y_m - f.tx_enu_m[1]))
        errs = np.array(list(row["errors_m"].values()))
        row["mean_error_m"] = float(errs.mean()) if errs.size else float("nan")
        out.append(row)
    return out


def decimate_flight(f: FlightSamples, rate_hz: float) -> FlightSamples:
    """Every k-th sample so that the rate is at most ``rate_hz`` (0: unchanged); times stay
    absolute."""
    if rate_hz <= 0 or len(f) < 3:
        return f
    dt = float(np.median(np.diff(f.t_s)))
    k = int(round(1.0 / (rate_hz * dt))) if dt > 0 else 1
    if k <= 1:
        return f
    keep = np.zeros(len(f), bool)
    keep[::k] = True
    return f.select(keep)


def _rich_progress() -> tuple[Any, Any]:
    """A rich progress bar and the ``(description, done, total)`` callback that drives it."""
    bar = Progress(
        TextColumn("{task.description:<40}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        transient=False,
    )
    task = bar.add_task("fits", total=1)

    def tick(desc: str, done: int, total: int) -> None:
        bar.update(task, description=desc[:40], completed=done, total=total)

    return bar, tick


def _laddered(
    base: Pipeline,
    flights: Sequence[FlightSamples],
    candidates: Sequence[Candidate],
    cfg: FitConfig,
    max_rungs: int,
    label: str,
    progress: bool | Any,
) -> list[Rung]:
    """The greedy ladder on the usable candidates, with a rich progress bar if ``progress`` is
    True (stopped whatever happens) or the caller's callback."""
    bar = None
    if progress is True:
        bar, progress = _rich_progress()
        bar.start()
    try:
        return ladder(
            base,
            flights,
            usable_candidates(candidates, flights, cfg.split),
            cfg,
            max_rungs=max_rungs,
            label=label,
            progress=progress or None,
        )
    finally:
        if bar is not None:
            bar.stop()


def _config(cfg: FitConfig, base: Pipeline, candidates: Sequence[Candidate]) -> dict[str, Any]:
    """The settings a diagnosis ran with (``Diagnosis.config``)."""
    return {
        "split": cfg.split,
        "n_chunks": cfg.n_chunks,
        "slope": cfg.slope,
        "loss": cfg.loss,
        "alpha": cfg.alpha,
        "min_rel": cfg.min_rel,
        "seed": cfg.seed,
        "rate_hz": cfg.rate_hz,
        "base": describe_params(base),
        "candidates": [c.name for c in candidates],
    }


def _statements(
    flights: Sequence[FlightSamples],
    als: Sequence[Alignment],
    rungs: Sequence[Rung],
    Ls: Sequence[int],
    cfg: FitConfig,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """What the flights can show: the near-nadir power statement (and whether the ladder named it)
    and the power statement along time, both on the final rung's residuals."""
    m = max(1, len(rungs[0].ranking))
    nadir = power_statement(
        [np.rad2deg(a.dep_b) for a in als],
        rungs[-1].residuals,
        Ls,
        make_folds(flights, cfg),
        cfg,
        m,
        seed=cfg.seed,
    )
    nadir["found"] = any(r.added == "near_nadir" for r in rungs)
    tpow = time_power_statement(
        flights, rungs[-1].residuals, make_folds(flights, cfg), cfg, m, cfg.split, seed=cfg.seed
    )
    return nadir, tpow


def _after_ladder(
    flights: Sequence[FlightSamples],
    als: Sequence[Alignment],
    rungs: Sequence[Rung],
    Ls: Sequence[int],
    cfg: FitConfig,
) -> list[Any]:
    """What is taken on the finished ladder, as four independent jobs in ``cfg.processes``
    processes: the residual structure of the first and of the last rung (each with its own
    generator from ``cfg.seed``, so the values do not depend on the processes), the footprints of
    the rungs, and the power statements.  Run one after another they kept both cores waiting on
    one for two seconds."""
    jobs: list[Callable[[], Any]] = [
        lambda: residual_structure(
            flights, rungs[0].residuals, np.random.default_rng([cfg.seed, 1])
        ),
        lambda: residual_structure(
            flights, rungs[-1].residuals, np.random.default_rng([cfg.seed, 2])
        ),
        lambda: {
            r.label: footprint(prev.pipes[0], r.pipes[0], flights) for prev, r in pairwise(rungs)
        },
        lambda: _statements(flights, als, rungs, Ls, cfg),
    ]
    return _map(lambda job: job(), jobs, 1, cfg.processes)


def diagnose(
    flights: Sequence[FlightSamples],
    base: Pipeline,
    candidates: Sequence[Candidate],
    cfg: FitConfig,
    base_label: str = "base",
    reference: Sequence[str] = REFERENCE_MODELS,
    pattern: str = "dipole",
    max_rungs: int = 6,
    localize: bool = True,
    area: Any = None,
    progress: bool | Any = False,
) -> Diagnosis:
    """Run the full diagnosis (see the module docstring).

    ``cfg.rate_hz`` > 0 first thins every flight to that sample rate (the residual is correlated
    over seconds, so 3 Hz loses little and makes every fit and bootstrap ~10x cheaper on 30 Hz
    logs). ``progress``: True for a rich progress bar, or a ``(description, done, total)`` callback.
    """
    flights = [decimate_flight(f, cfg.rate_hz) for f in flights]
    rng = np.random.default_rng(cfg.seed)
    als = [align(f) for f in flights]
    gaps = [model_gap(base_pipeline(m, pattern), flights, cfg, m) for m in reference]
    bg = model_gap(base, flights, cfg, base_label)
    if base_label not in reference:
        gaps.append(bg)
    Ls = [block_length(r) for r in bg.residuals]
    breakdown = residual_breakdown(als, bg.residuals, Ls, rng)
    fmap = field_map(als, bg.residuals, Ls, rng)
    rungs = _laddered(base, flights, candidates, cfg, max_rungs, base_label, progress)
    loc = localization_cost(rungs, flights, area, split=cfg.split) if localize else []
    struct_base, struct_final, fps, (nadir, tpow) = _after_ladder(flights, als, rungs, Ls, cfg)
    struct = {"base": struct_base, "final": struct_final}
    frames = {r.label: r.frame for r in rungs if r.frame is not None}
    return Diagnosis(
        flights,
        als,
        base_label,
        gaps,
        breakdown,
        fmap,
        rungs,
        loc,
        Ls,
        _config(cfg, base, candidates),
        struct,
        fps,
        nadir,
        tpow,
        frames,
    )


def rung_table(d: Diagnosis) -> list[dict[str, Any]]:
    """Per rung: held-out gap pooled and per flight, what was added, fitted parameters."""
    rows = []
    for r in d.rungs:
        per = {
            f.name: summarize(x[np.isfinite(x)]).as_dict()
            for f, x in zip(d.flights, r.residuals, strict=True)
        }
        rows.append(
            {
                "rung": r.label,
                "added": r.added,
                "params": r.params,
                "model": r.describe(),
                "pooled": summarize(_pooled(r.residuals)).as_dict(),
                "per_flight": per,
            }
        )
    return rows
