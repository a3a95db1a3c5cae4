"""From a diagnosis to a physics family: each ladder effect fitted per flight, its spread, the
residual structure.

Why: the diagnosis says *which* effects close the gap on the real flights; the rest of the product
(simulated benchmarks, training sets) needs a *distribution* of physics that spreads the way the
real flights spread (``mission.physics.family``, schema 1).  Every effect the ladder added is mapped
to what a model spec can express (``FAMILY_EFFECT``: the free-form UAV map becomes the UAV antenna
pattern and heading it resembles, the excess loss a path-gain slope, the smoothers the correlated
residual), fitted on each flight alone (all its samples, soft-L1), and its per-flight values become
a distribution (normal over flights, physical bounds; a categorical pattern becomes a variant with
its share of flights).  The residual of each flight after that fit, held out (two folds of alternate
chunks), gives the correlated shadowing (gaussian variogram over space: sigma, range, nugget), the
white noise and the held-out p90; the offsets give ``offset_db``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mission.gap.candidates import select
from mission.gap.describe import describe_params
from mission.gap.fit import (
    FitConfig,
    Fold,
    _map,
    decimate,
    fit_candidate,
    longest_first,
    make_folds,
    minimize_from_grid,
    objective,
    residuals,
)
from mission.gap.pipeline import Pipeline, Selection
from mission.gap.temporal import time_columns
from mission.importers.afar import AFAR2023_SUSPECT_NOTE, is_afar2023_suspect
from mission.physics.family import (
    DRIFT_ORDER,
    azimuth_basis,
    azimuth_coordinate,
    radial_coordinate,
)
from mission.physics.presets import build_model
from mission.physics.shadowing import fit_variogram, standardized_marginal
from mission.robust import robust_offset
from mission.samples import FlightSamples

FAMILY_BASE: dict[str, Any] = {
    "base": "free-space",
    "attitude": "yaw",
    "rx_pattern": "isotropic",
    "tx_pattern": "isotropic",
}
# ladder rung -> family effect (what a model spec can express); None: nothing a spec holds
FAMILY_EFFECT: dict[str, str | None] = {
    "rx_pattern": "rx_antenna",
    "rx_mounting": "rx_antenna",
    "rx_gain_map": "rx_antenna",
    "attitude": "rx_antenna",
    "yaw_attitude": "rx_antenna",
    "tx_pattern": "tx_antenna",
    "tx_mounting": "tx_antenna",
    "tx_gain_map": "tx_antenna",
    "excess_loss": "path_gain_slope",
    "path_gain_slope": "path_gain_slope",
    "ground_reflection": "ground",
    "leg_shadowing": "leg_shadowing",
    "spatial_shadowing": "residual",
    "site_map": "residual",
    "time_offset": None,
    "receiver": None,
    "tx_tilt": None,
}
# family effect -> the named candidates fitted per flight, in this order
EFFECT_FITS: dict[str, tuple[str, ...]] = {
    "rx_antenna": ("rx_pattern",),
    "tx_antenna": ("tx_pattern",),
    "path_gain_slope": ("path_gain_slope",),
    "ground": ("ground_reflection",),
    "leg_shadowing": ("leg_shadowing",),
}
EFFECT_ORDER = ("rx_antenna", "tx_antenna", "path_gain_slope", "ground", "leg_shadowing")
# spec parameter -> physical bounds of its distribution
BOUNDS = {
    "path_gain_slope": (-1.5, 5.0),
    "leg_shadowing_beta": (0.0, 8.0),
    "ground.eps_r": (1.1, 80.0),
    "ground.sigma_s_m": (0.0, 1.0),
    "shadowing_db": (0.0, 30.0),
    "shadowing_corr_m": (5.0, 400.0),
    "noise_db": (0.0, 20.0),
    "offset_db": (-200.0, 200.0),
    "time_drift_db": (0.0, 30.0),
    "radial_db": (0.0, 30.0),
    "azimuth_db": (0.0, 30.0),
}
PATTERN_KEYS = ("rx_pattern", "rx_flipped", "tx_pattern", "tx_flipped")
FIT_SAMPLES = (
    1200  # samples per fit (the residual is correlated over ~10 s: more add time, not information)
)
MIN_HEIGHT_M = (
    10.0  # airborne samples only: take-off and landing see the rover through the ground clutter
)


def team_of(name: str) -> str:
    """Team of an AFAR flight from its name (``..exp_288_loc_1``, ``288_loc_1``, ``288-loc1``), else
    the name."""
    m = re.search(r"(\d+)[_-]loc_?\d+", name)
    return m.group(1) if m else name


def effects_of_ladder(added: Sequence[str | None]) -> tuple[list[str], list[str]]:
    """Family effects (in ``EFFECT_ORDER``) of the rungs ``added``, and the rungs no spec can
    hold."""
    eff = {FAMILY_EFFECT.get(a) for a in added if a}
    left = [a for a in added if a and FAMILY_EFFECT.get(a, None) is None]
    return [e for e in EFFECT_ORDER if e in eff], left


def spec_of(pipe: Pipeline) -> dict[str, Any]:
    """The model spec (``build_model`` keys) of a fitted family pipeline."""
    d = describe_params(pipe)
    spec = dict(FAMILY_BASE)
    for end in ("rx", "tx"):
        pat = d.get(f"{end}_pattern", "isotropic")
        spec[f"{end}_pattern"] = pat.split()[0]
        spec[f"{end}_flipped"] = pat.endswith("flipped")
        if pat.startswith("measured"):
            spec[f"{end}_heading_deg"] = float(d.get(f"{end}_heading_deg", 0.0)) % 360.0
    if "eps_r" in d:
        spec["ground"] = {
            "eps_r": float(d["eps_r"]),
            "sigma_s_m": float(d["sigma_s_m"]),
            "polarization": str(d["polarization"]),
        }
    if "path_gain_n_extra" in d:
        spec["path_gain_slope"] = float(d["path_gain_n_extra"])
    if "beta" in d:
        spec["leg_shadowing_beta"] = float(d["beta"])
    return spec


def base_family_pipeline() -> Pipeline:
    return Pipeline(build_model(FAMILY_BASE, name="family-base"))


# continuous spec parameters polished jointly: (key, start grid, simplex step, lo, hi); headings are
# periodic
# offsets from the sequential fit
_JOINT = (
    (
        "rx_heading_deg",
        (0.0, 90.0, 180.0, 270.0),
        15.0,
        -np.inf,
        np.inf,
    ),
    ("tx_heading_deg", (0.0, 120.0, 240.0), 20.0, -np.inf, np.inf),
    ("path_gain_slope", (), 0.3, -1.5, 5.0),
    ("leg_shadowing_beta", (), 0.3, 0.0, 8.0),
)


def fit_effects(
    pipe: Pipeline,
    flight: FlightSamples,
    idx: np.ndarray,
    effects: Sequence[str],
    cfg: FitConfig,
    rng: np.random.Generator,
) -> Pipeline:
    """The family effects fitted in order on one flight's samples ``idx`` (multi-start fits of
    ``fit.py``), then their continuous parameters polished jointly (``polish``: a heading fitted
    before the slope is biased). An antenna pattern is chosen with its heading fitted for every
    choice (a measured pattern at a wrong heading loses to a dipole)."""
    for eff in effects:
        names = EFFECT_FITS[eff]
        if eff in ("rx_antenna", "tx_antenna"):
            pipe = _fit_antenna(pipe, flight, idx, names, cfg, rng)
            continue
        for name in names:
            cand = select([name])[0]
            if cand.applicable(pipe):
                pipe = fit_candidate(cand, pipe, [flight], [idx], cfg, rng).pipeline
    return polish(pipe, flight, idx, cfg) if effects else pipe


def _fit_antenna(
    pipe: Pipeline,
    flight: FlightSamples,
    idx: np.ndarray,
    names: Sequence[str],
    cfg: FitConfig,
    rng: np.random.Generator,
) -> Pipeline:

    pat = select([names[0]])[0]
    mount = select([f"{names[0].split('_')[0]}_mounting"])[0]
    ii = Selection([flight], [decimate(idx, cfg.fit_max_samples)])
    best, best_loss = pipe, objective(pipe, [flight], ii, cfg)
    for choice in pat.choices(pipe) or ({},):
        p = pat.build(pipe, {}, choice)
        if mount.applicable(p):
            p = fit_candidate(mount, p, [flight], [idx], cfg, rng).pipeline
        loss = objective(p, [flight], ii, cfg)
        if loss < best_loss:
            best, best_loss = p, loss
    return best


def polish(pipe: Pipeline, flight: FlightSamples, idx: np.ndarray, cfg: FitConfig) -> Pipeline:
    """Joint multi-start Nelder-Mead over the spec's continuous parameters (headings on a grid, the
    others from the sequential fit), the three best starts polished."""

    spec = spec_of(pipe)
    if "ground" in spec:  # the ground's parameters stay as the sequential fit left them
        return pipe
    keys = [j for j in _JOINT if j[0] in spec]
    if not keys:
        return pipe
    ii = Selection([flight], [decimate(idx, cfg.fit_max_samples)])

    def make(x: np.ndarray) -> Pipeline:
        sp = dict(spec)
        for (k, _, _, lo, hi), v in zip(keys, x, strict=True):
            sp[k] = float(np.clip(v, lo, hi))
        return Pipeline(build_model(sp, name="family"))

    def f(x: np.ndarray) -> float:
        return objective(make(x), [flight], ii, cfg)

    grid = list(
        itertools.product(
            *[(spec[k] + np.array(g)) % 360.0 if g else (spec[k],) for k, g, _, _, _ in keys]
        )
    )
    x, _ = minimize_from_grid(
        f,
        np.array(grid, dtype=float),
        [j[2] for j in keys],
        cfg.max_evals,
        n_starts=2,
        xatol=cfg.polish_xatol,
        fatol=cfg.polish_fatol,
    )
    new = make(x)
    return new if f(x) <= objective(pipe, [flight], ii, cfg) else pipe


@dataclass
class FlightFit:
    """One flight's family fit: spec (all samples), offset, held-out residual and its variogram."""

    name: str
    team: str
    spec: dict[str, Any]
    offset_db: float
    heldout: np.ndarray = field(repr=False)
    variogram: dict[str, float]
    heldout_p90_db: float
    excluded: str = (
        ""  # why the family's distributions leave this flight out (e.g. a suspect truth label)
    )

    def as_dict(self) -> dict[str, Any]:
        d = {
            "flight": self.name,
            "team": self.team,
            "spec": self.spec,
            "offset_db": self.offset_db,
            "residual": self.variogram,
            "heldout_p90_db": self.heldout_p90_db,
            "n": int(len(self.heldout)),
        }
        return d | ({"excluded": self.excluded} if self.excluded else {})


# the per-flight nuisance a family can draw: kind -> its key in ``nuisance`` (``physics.family``)
NUISANCE_KINDS = {"time": "time_drift_db", "radial": "radial_db", "azimuth": "azimuth_db"}


def structure_kinds(structure: bool | Sequence[str]) -> tuple[str, ...]:
    """The nuisance kinds of a ``structure`` argument: True is the time drift alone (the first
    structured family), False none, else the kinds named (``NUISANCE_KINDS``)."""
    if structure is True:
        return ("time",)
    if not structure:
        return ()
    bad = [k for k in structure if k not in NUISANCE_KINDS]
    if bad:
        raise ValueError(f"unknown nuisance kind(s) {bad} (expected {', '.join(NUISANCE_KINDS)})")
    return tuple(structure)


def structure_of(structure: bool, radial: bool = False, azimuth: bool = False):
    """The ``structure`` argument of the command-line flags: ``--family-radial`` and
    ``--family-azimuth`` each add their kind beside the time drift (and imply the structure)."""
    extra = (("radial",) if radial else ()) + (("azimuth",) if azimuth else ())
    return ("time", *extra) if extra else structure


def nuisance_stds(
    flight: FlightSamples, r: np.ndarray, kinds: Sequence[str] = ("time",)
) -> dict[str, float]:
    """Per nuisance kind, the std of its part of the residual ``r``: one least-squares fit of the
    kinds' smooth bases together to the finite samples about their mean (``time``: the gap's
    smooth time basis, ``temporal.time_columns``, Legendre P_1..P_4 of the time scaled to [-1, 1],
    no steps; ``radial``: Legendre P_1..P_4 of ``physics.family.log_distance_unit``, the distance
    to the rover; ``azimuth``: cos and sin of k az_b, k = 1..4, of the rover's body azimuth,
    ``physics.family.azimuth_basis``; each column about its mean, as the residual is), so that
    what several explain is not counted twice; 0 each with fewer than 20 samples."""
    ok = np.isfinite(r)
    out = {NUISANCE_KINDS[k]: 0.0 for k in kinds}
    if ok.sum() < 20 or not kinds:
        return out
    blocks = []
    for k in kinds:
        if k == "time":
            if flight.t_s is None:
                return out
            t = np.asarray(flight.t_s, dtype=float)
            blocks.append(time_columns(t[ok], float(t[0]), float(t[-1]), np.zeros(0))[0])
        elif k == "radial":
            if flight.tx_enu_m is None:
                return out
            u = radial_coordinate(flight.tx_enu_m, flight.enu_m[ok])
            blocks.append(np.polynomial.legendre.legvander(u, DRIFT_ORDER)[:, 1:])
        else:
            if flight.tx_enu_m is None or flight.attitude_rad is None:
                return out
            az = azimuth_coordinate(flight.tx_enu_m, flight.enu_m[ok], flight.attitude_rad[ok])
            blocks.append(azimuth_basis(az))
    blocks = [b - b.mean(axis=0) for b in blocks]  # about their means, as y: no intercept lost
    X = np.column_stack(blocks)
    y = r[ok] - np.mean(r[ok])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    j = 0
    for k, b in zip(kinds, blocks, strict=True):
        out[NUISANCE_KINDS[k]] = float(np.std(b @ coef[j : j + b.shape[1]]))
        j += b.shape[1]
    return out


def time_drift_std(flight: FlightSamples, r: np.ndarray) -> float:
    """The std of the smooth drift over the flight's time in the residual ``r``
    (``nuisance_stds`` of the time basis alone)."""
    return nuisance_stds(flight, r, ("time",))["time_drift_db"]


def fit_flight(
    flight: FlightSamples,
    effects: Sequence[str],
    cfg: FitConfig,
    seed: int = 0,
    label: str | None = None,
    structure: bool | Sequence[str] = False,
    covariance: str = "gaussian",
) -> FlightFit:
    """Fit the family effects on one flight; residual structure from two folds of alternate
    chunks.  ``structure``: also the per-flight nuisance (``structure_kinds``: True is the time
    drift, ``time_drift_db``; ``("time", "radial")`` adds ``radial_db``; ``nuisance_stds`` of the
    held-out residual), taken out of the shadowing (only what is left is drawn as shadowing).
    ``covariance``: the variogram fitted to the held-out residual (the family draws that one)."""
    rng = np.random.default_rng(seed)
    cfg = FitConfig(**{**cfg.__dict__, "fit_max_samples": min(cfg.fit_max_samples, FIT_SAMPLES)})
    flight = (
        flight.select(flight.enu_m[:, 2] > MIN_HEIGHT_M)
        if (flight.enu_m[:, 2] > MIN_HEIGHT_M).sum() > 200
        else flight
    )
    base = base_family_pipeline()
    every = np.arange(len(flight))
    pipe = fit_effects(base, flight, every, effects, cfg, rng)
    off = float(robust_offset(flight.rss_dbm - pipe.predict(flight)))
    held = np.full(len(flight), np.nan)
    bcfg = FitConfig(**{**cfg.__dict__, "split": "blocks", "n_chunks": 8})
    for fold in make_folds([flight], bcfg):
        p = fit_effects(base, flight, fold.train[0], effects, cfg, rng)
        held[fold.test[0]] = residuals(p, [flight], fold.test, cfg)[0]
    vg = residual_variogram(flight, held, rng, covariance)
    p90 = float(np.quantile(np.abs(held[np.isfinite(held)]), 0.9))
    # the variogram's sill (lags up to 200 m, gaussian) misses the heavy tail and the largest
    # scales; the family's shadowing std is set so that the gaussian p90 1.645 sqrt(s^2 + n^2)
    # equals the held-out p90
    vg["variogram_sigma_db"] = vg["shadowing_db"]
    nuis = nuisance_stds(flight, held, structure_kinds(structure))
    vg.update(nuis)
    vg["shadowing_db"] = float(
        math.sqrt(
            max((p90 / 1.645) ** 2 - vg["noise_db"] ** 2 - sum(v * v for v in nuis.values()), 0.0)
        )
    )
    vg["sill_db"] = float(math.hypot(vg["variogram_sigma_db"], vg["noise_db"]))
    return FlightFit(
        label or flight.name, team_of(label or flight.name), spec_of(pipe), off, held, vg, p90
    )


def residual_variogram(
    flight: FlightSamples, r: np.ndarray, rng: np.random.Generator, covariance: str = "gaussian"
) -> dict[str, float]:
    """Variogram over space of the ``covariance`` the family draws (``simulate_rss``; Gaussian
    unless the family says otherwise): sigma and range; the white noise from consecutive samples
    (half the mean squared difference of neighbours < 10 m apart), not from the variogram's
    nugget, which a fit to 5 m lag bins puts too low (and a re-fit of flights simulated with it
    lower still)."""
    ok = np.isfinite(r)
    vg = fit_variogram(
        flight.enu_m[ok, :2],
        r[ok] - np.mean(r[ok]),
        rng,
        kind=covariance,
        max_lag=200.0,
        n_bins=40,
        max_points=1500,
        n_boot=0,
    )
    d = np.diff(r)
    step = np.linalg.norm(np.diff(flight.enu_m[:, :2], axis=0), axis=1)
    near = np.isfinite(d) & (step < 10.0)
    noise = float(np.sqrt(0.5 * np.mean(d[near] ** 2))) if near.sum() > 10 else float(vg.nugget_db)
    return {
        "shadowing_db": float(vg.sigma_db),
        "shadowing_corr_m": float(vg.corr_len),
        "noise_db": noise,
        "sill_db": float(math.hypot(vg.sigma_db, noise)),
        "variogram_nugget_db": float(vg.nugget_db),
    }


def _spread(vals: Sequence[float], teams: Sequence[str]) -> dict[str, Any]:
    v = np.asarray(vals, dtype=float)
    out: dict[str, Any] = {
        "mean": float(v.mean()),
        "sd": float(v.std(ddof=1)) if len(v) > 1 else 0.0,
        "min": float(v.min()),
        "max": float(v.max()),
        "per_flight": v.round(4).tolist(),
    }
    by = {}
    for t in sorted(set(teams)):
        w = v[[k for k, tt in enumerate(teams) if tt == t]]
        by[t] = {
            "n": len(w),
            "mean": float(w.mean()),
            "sd": float(w.std(ddof=1)) if len(w) > 1 else 0.0,
        }
    if len(by) > 1:
        out["per_team"] = by
        # between-team share of the spread (what a new team may add beyond a new flight of a known
        # team)
        out["team_sd"] = float(np.std([b["mean"] for b in by.values()], ddof=1))
    return out


def _normal(s: dict[str, Any], key: str) -> Any:
    """A parameter's family distribution: normal over flights (sd at least the between-team sd),
    clipped."""
    sd = max(s["sd"], s.get("team_sd", 0.0))
    if sd <= 0:
        return s["mean"]
    lo, hi = BOUNDS.get(key, (-np.inf, np.inf))
    d = {"dist": "normal", "mean": round(s["mean"], 4), "sd": round(sd, 4)}
    if np.isfinite(lo):
        d.update(lo=lo, hi=hi)
    return d


def offset_distribution(off: dict[str, Any], per_flight: bool = False) -> Any:
    """The family's offset: normal over flights, or with per-flight structure one of the real
    flights' offsets (``empirical``): a normal over five offsets (56-94 dB, sd 16.5) drew 111 dB,
    a receiver reading no real flight comes near (the logs top out at 33 dB, the reader refuses
    over 100)."""
    if per_flight and len(off["per_flight"]) > 1:
        return {"dist": "empirical", "values": [round(float(v), 4) for v in off["per_flight"]]}
    return _normal(off, "offset_db")


def _circular(vals: Sequence[float]) -> tuple[Any, dict[str, Any]]:
    a = np.deg2rad(np.asarray(vals, dtype=float))
    c, s = np.cos(a).mean(), np.sin(a).mean()
    mean = float(np.rad2deg(np.arctan2(s, c)) % 360.0)
    R = float(np.hypot(c, s))
    sd = float(np.rad2deg(math.sqrt(max(0.0, -2.0 * math.log(max(R, 1e-9))))))
    info = {"mean": mean, "circular_sd_deg": sd, "per_flight": np.round(vals, 2).tolist()}
    if sd > 90.0 or len(a) < 2:
        return ({"dist": "uniform", "lo": 0.0, "hi": 360.0} if len(a) > 1 else mean), info
    return {"dist": "normal", "mean": round(mean, 2), "sd": round(max(sd, 5.0), 2)}, info


def build_family(
    fits: Sequence[FlightFit],
    effects: Sequence[str],
    name: str = "family",
    source: dict[str, Any] | None = None,
    not_in_family: Sequence[str] = (),
    shadowing_over: str = "ground",
    marginal: bool = False,
    covariance: str = "gaussian",
) -> dict[str, Any]:
    """The schema-1 family record (``mission.physics.family``) of per-flight fits, with spreads
    and intervals. Flights marked ``excluded`` are listed in ``per_flight`` but enter no
    distribution. ``shadowing_over``: what the drawn shadowing is fixed to (``"path"``: along the
    track, as the diagnosis's "correlated within flights" says of the real residual);
    ``marginal``: the shadowing takes the shape of the flights' held-out residuals
    (``heldout_marginal``), not a Gaussian one; ``covariance``: the one the fits' variograms were
    fitted with (``fit_flight``), recorded for the draws."""
    every = list(fits)
    fits = [f for f in fits if not f.excluded] or every
    teams = [f.team for f in fits]
    spec: dict[str, Any] = dict(FAMILY_BASE)
    spreads: dict[str, Any] = {}
    combos: dict[tuple, int] = {}
    for f in fits:
        key = tuple(
            f.spec.get(k, False if k.endswith("flipped") else "isotropic") for k in PATTERN_KEYS
        )
        combos[key] = combos.get(key, 0) + 1
    variants = [
        {"p": round(n / len(fits), 6), "spec": dict(zip(PATTERN_KEYS, k, strict=True))}
        for k, n in sorted(combos.items(), key=lambda kv: -kv[1])
    ]
    if variants:
        variants[0]["p"] = round(1.0 - sum(v["p"] for v in variants[1:]), 6)
    for end in ("rx", "tx"):
        hd = [f.spec[f"{end}_heading_deg"] for f in fits if f"{end}_heading_deg" in f.spec]
        if hd:
            spec[f"{end}_heading_deg"], spreads[f"{end}_heading_deg"] = _circular(hd)
    for key in ("path_gain_slope", "leg_shadowing_beta"):
        if any(key in f.spec for f in fits):
            s = _spread([f.spec.get(key, 0.0) for f in fits], teams)
            spec[key], spreads[key] = _normal(s, key), s
    if any("ground" in f.spec for f in fits):
        g: dict[str, Any] = {}
        for k in ("eps_r", "sigma_s_m"):
            s = _spread([f.spec["ground"][k] for f in fits if "ground" in f.spec], teams)
            g[k], spreads[f"ground.{k}"] = _normal(s, f"ground.{k}"), s
        pol = [f.spec["ground"]["polarization"] for f in fits if "ground" in f.spec]
        g["polarization"] = max(set(pol), key=pol.count)
        spec["ground"] = g
    residual = {}
    for k in ("shadowing_db", "shadowing_corr_m", "noise_db"):
        s = _spread([f.variogram[k] for f in fits], teams)
        residual[k], spreads[k] = _normal(s, k), s
    nuisance = {}
    for key in NUISANCE_KINDS.values():
        if all(key in f.variogram for f in fits):
            s = _spread([f.variogram[key] for f in fits], teams)
            nuisance[key], spreads[key] = _normal(s, key), s
    off = _spread([f.offset_db for f in fits], teams)
    spreads["offset_db"] = off
    p90 = _spread([f.heldout_p90_db for f in fits], teams)
    held = np.concatenate([f.heldout[np.isfinite(f.heldout)] for f in fits])
    p90["pooled"] = float(np.quantile(np.abs(held), 0.9)) if held.size else float("nan")
    sill = _spread([f.variogram["sill_db"] for f in fits], teams)
    spreads["sill_db"] = sill
    return {
        "schema": 1,
        "name": name,
        "description": "physics family fitted by rfsl gap --family: each ladder effect fitted per "
        "flight (airborne samples, > 10 m) as a model spec (normal over flights, sd at least the "
        "between-team sd; antenna patterns as variants by share of flights), the held-out "
        "residual's gaussian variogram per flight (shadowing sigma and range) and white noise "
        "(neighbour differences), the offsets; flights with 'excluded' enter no distribution",
        "source": source or {},
        "spec": spec,
        "variants": variants,
        "residual": residual,
        "offset_db": offset_distribution(off, per_flight=bool(nuisance)),
        **({"nuisance": nuisance} if nuisance else {}),
        **({"shadowing_over": shadowing_over} if shadowing_over != "ground" else {}),
        **({"shadowing_marginal": heldout_marginal(fits)} if marginal else {}),
        **({"shadowing_covariance": covariance} if covariance != "gaussian" else {}),
        "effects": list(effects),
        "not_in_family": list(not_in_family),
        "spread": spreads,
        "checks": {"heldout_p90_db": p90, "sill_db": sill, "intervals": intervals(spreads)},
        "per_flight": [f.as_dict() for f in every],
    }


def heldout_marginal(fits: Sequence[FlightFit]) -> dict[str, list[float]]:
    """The standardized shape of the flights' held-out residuals (each flight's about its mean,
    over its std, then pooled; ``physics.shadowing.standardized_marginal``): the family's
    ``shadowing_marginal``.  The whole residual's shape stands for the shadowing's, the largest
    part of it; the white noise and the drift are drawn Gaussian and smooth beside it, so a
    simulated flight's whole residual is a little less skewed than the real one."""
    z = []
    for f in fits:
        r = f.heldout[np.isfinite(f.heldout)]
        if r.size > 1 and r.std() > 0:
            z.append((r - r.mean()) / r.std())
    p, q = standardized_marginal(np.concatenate(z))
    return {"p": list(p), "q": list(q)}


def intervals(spreads: dict[str, Any]) -> dict[str, list[float]]:
    """Per parameter, the interval a re-diagnosis must fall in: the per-flight range widened by one
    standard error of the flights' mean on each side (a re-fit mean over as many flights scatters by
    about that)."""
    out = {}
    for k, s in spreads.items():
        if "min" not in s:
            continue
        n = max(len(s["per_flight"]), 1)
        se = max(s["sd"], s.get("team_sd", 0.0)) / math.sqrt(n)
        out[k] = [s["min"] - se, s["max"] + se]
    return out


def fit_family(
    flights: Sequence[FlightSamples],
    effects: Sequence[str],
    cfg: FitConfig,
    labels: Sequence[str] | None = None,
    seed: int = 0,
    structure: bool | Sequence[str] = False,
    covariance: str = "gaussian",
    **kw: Any,
) -> tuple[dict[str, Any], list[FlightFit]]:
    """Fit ``effects`` on every flight and build the family record (``build_family``);
    ``structure``: with the per-flight nuisance; ``covariance``: the shadowing's
    (``fit_flight``)."""

    labels = list(labels) if labels is not None else [f.name for f in flights]
    jobs = list(enumerate(zip(flights, labels, strict=True)))
    # the longest flights first (a job's seed is its flight's index, so the order changes no bit):
    # the last flights handed out are the short ones, and the processes finish together
    fits = _map(
        lambda j: fit_flight(j[1][0], effects, cfg, seed + j[0], j[1][1], structure, covariance),
        jobs,
        cfg.workers,
        cfg.processes,
        order=longest_first([float(len(f.rss_dbm)) for f in flights]),
    )
    for f in fits:
        if is_afar2023_suspect(f.name):
            f.excluded = AFAR2023_SUSPECT_NOTE
    return build_family(fits, effects, covariance=covariance, **kw), fits


__all__ = [
    "FAMILY_EFFECT",
    "Fold",
    "FlightFit",
    "build_family",
    "effects_of_ladder",
    "fit_family",
    "fit_flight",
    "team_of",
]
