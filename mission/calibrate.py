"""Calibrate a physics preset on real flights with known transmitters, with held-out figures (``rfsl
calibrate``).

A *configuration* is a model spec (``mission.physics.presets`` layout) plus the names of its free
parameters (UAV-antenna heading, path-gain slope, leg-shadowing beta, ground permittivity).
Fitting: every flight gets its own free RSS offset (real receivers are not calibrated, SPEC section
5) and the loss is soft-L1 (``mission.robust``), minimised by Nelder-Mead from the best points of a
start grid (the heading is multimodal).

Held-out figures: flights are put in *groups* (a team, a day, a vehicle: whatever must not leak);
every group is scored by the configuration fitted on the other groups (leave one group out).  The
configuration with the lowest held-out soft-L1 is chosen, refitted on all flights, and written as a
preset record that says what it was fitted on, its per-group folds and its held-out figures
(``preset_record``).
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Callable, Sequence

import numpy as np

from mission.errors import InputError
from mission.gap.optim import minimize_from_grid
from mission.physics.presets import build_model
from mission.robust import offset_residual, per_sample_loss
from mission.samples import FlightSamples

F_SCALE_DB = 6.0
LOSS = "soft_l1"

# A configuration: fixed choices (``spec``) + free parameters (``free``), fitted by ``fit_config``.
CONFIGS: dict[str, dict] = {
    "fs_iso": {"spec": {"base": "free-space"}, "free": []},
    "e2r_dipole_default": {
        "spec": {"base": "e2r", "tx_pattern": "dipole", "rx_pattern": "dipole"},
        "free": [],
    },
    "fs_slope": {"spec": {"base": "free-space"}, "free": ["n_extra"]},
    "fs_rxflip": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": True,
        },
        "free": ["rx_heading_deg"],
    },
    "fs_rxflip_yaw": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": "yaw",
        },
        "free": ["rx_heading_deg"],
    },
    "fs_rxflip_yaw_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": "yaw",
        },
        "free": ["rx_heading_deg", "n_extra"],
    },
    "fs_rxflip_yaw_slope_legs": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": "yaw",
        },
        "free": ["rx_heading_deg", "n_extra", "beta"],
    },
    "fs_rxup_yaw": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": False,
            "attitude": "yaw",
        },
        "free": ["rx_heading_deg"],
    },
    "fs_rxdipole_slope": {
        "spec": {"base": "free-space", "rx_pattern": "dipole", "attitude": True},
        "free": ["n_extra"],
    },
    "tworay_rxflip_yaw_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": "yaw",
        },
        "free": ["rx_heading_deg", "n_extra", "log10_eps"],
    },
    "fs_rxflip_yaw_txmeas_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "tx_pattern": "measured",
            "attitude": "yaw",
        },
        "free": ["rx_heading_deg", "n_extra"],
    },
    "fs_rxflip_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": True,
        },
        "free": ["rx_heading_deg", "n_extra"],
    },
    "fs_rxflip_noatt_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": False,
        },
        "free": ["rx_heading_deg", "n_extra"],
    },
    "fs_rxflip_txmeas_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "tx_pattern": "measured",
            "attitude": True,
        },
        "free": ["rx_heading_deg", "n_extra"],
    },
    "fs_rxflip_txdipole_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "tx_pattern": "dipole",
            "attitude": True,
        },
        "free": ["rx_heading_deg", "n_extra"],
    },
    "fs_rxflip_slope_legs": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": True,
        },
        "free": ["rx_heading_deg", "n_extra", "beta"],
    },
    "tworay_rxflip_slope": {
        "spec": {
            "base": "free-space",
            "rx_pattern": "measured",
            "rx_flipped": True,
            "attitude": True,
        },
        "free": ["rx_heading_deg", "n_extra", "log10_eps"],
    },
}
DEFAULT_CONFIGS = (
    "fs_iso",
    "fs_slope",
    "fs_rxflip",
    "fs_rxflip_yaw",
    "fs_rxflip_yaw_slope",
    "fs_rxup_yaw",
)
BOUNDS = {
    "rx_heading_deg": (-np.inf, np.inf),
    "n_extra": (-1.0, 4.0),
    "beta": (0.0, 4.0),
    "log10_eps": (0.0, 2.0),
}
START_GRID = {
    "rx_heading_deg": tuple(np.arange(0.0, 360.0, 45.0)),
    "n_extra": (0.0, 1.0, 2.0),
    "beta": (0.0, 1.0, 2.0),
    "log10_eps": (0.2, 1.2),
}


def config(name: str) -> dict:
    """The configuration ``name`` (``CONFIGS``); an unknown name is an InputError listing the known
    ones."""
    if name not in CONFIGS:
        raise InputError(
            f"unknown calibration configuration {name!r} (known: {', '.join(CONFIGS)})",
            field="--configs",
        )
    return CONFIGS[name]


def spec_with(cfg: dict, theta: dict[str, float]) -> dict:
    """The model spec of configuration ``cfg`` with free parameters ``theta`` filled in."""
    spec = dict(cfg["spec"])
    if "rx_heading_deg" in theta:
        spec["rx_heading_deg"] = float(theta["rx_heading_deg"]) % 360.0
    if "n_extra" in theta:
        spec["path_gain_slope"] = float(theta["n_extra"])
    if "beta" in theta:
        spec["leg_shadowing_beta"] = float(theta["beta"])
    if "log10_eps" in theta:
        spec["ground"] = {"eps_r": float(10 ** theta["log10_eps"]), "sigma_s_m": 0.005}
    return spec


AttitudeFn = Callable[[np.ndarray], np.ndarray | None]


def predict(model, f: FlightSamples, idx=None, attitude: AttitudeFn | None = None) -> np.ndarray:
    """Model RSS along flight ``f`` (optionally at samples ``idx``) with its logged attitude, or
    with ``attitude(logged)`` (an attitude-convention experiment; None from it = no attitude)."""
    sl = slice(None) if idx is None else idx
    att = f.attitude_rad[sl] if attitude is None else attitude(f.attitude_rad[sl])
    return np.asarray(model.rss_dbm(f.tx_enu_m, f.enu_m[sl], att), dtype=float)


def gap_stats(model, f: FlightSamples, attitude: AttitudeFn | None = None) -> dict:
    """Held-out fit of ``model`` on flight ``f``: |measured - model - offset| median / p90, rms,
    soft-L1."""
    r = offset_residual(f.rss_dbm, predict(model, f, None, attitude), loss=LOSS, f_scale=F_SCALE_DB)
    a = np.abs(r)
    return {
        "median_abs_db": float(np.median(a)),
        "p90_abs_db": float(np.quantile(a, 0.9)),
        "rms_db": float(np.sqrt(np.mean(r * r))),
        "soft_l1": float(np.mean(per_sample_loss(r, LOSS, F_SCALE_DB))),
        "n": int(r.size),
    }


def fit_config(
    cfg: dict,
    flights: Sequence[FlightSamples],
    max_samples: int = 1200,
    max_evals: int = 80,
    attitude: AttitudeFn | None = None,
) -> tuple[dict, float]:
    """Fit the free parameters of ``cfg`` on ``flights`` (per-flight offsets, soft-L1) -> (spec,
    train loss)."""
    idx = [np.arange(0, len(f), max(1, math.ceil(len(f) / max_samples))) for f in flights]
    names = list(cfg["free"])

    def loss(x) -> float:
        th = {n: float(np.clip(v, *BOUNDS[n])) for n, v in zip(names, x, strict=True)}
        m = build_model(spec_with(cfg, th))
        tot, n = 0.0, 0
        for f, i in zip(flights, idx, strict=True):
            r = offset_residual(
                f.rss_dbm[i], predict(m, f, i, attitude), loss=LOSS, f_scale=F_SCALE_DB
            )
            tot += float(per_sample_loss(r, LOSS, F_SCALE_DB).sum())
            n += r.size
        return tot / max(n, 1)

    if not names:
        return spec_with(cfg, {}), loss([])
    grid = (
        np.array(np.meshgrid(*[START_GRID[n] for n in names], indexing="ij"))
        .reshape(len(names), -1)
        .T
    )
    steps = [20.0 if n == "rx_heading_deg" else 0.3 for n in names]
    # two best starts (the heading is multimodal); the fit procedure is the gap candidates' (one
    # home)
    x, fun = minimize_from_grid(loss, grid, steps, max_evals, n_starts=2, xatol=1e-2, fatol=1e-4)
    th = {n: float(np.clip(v, *BOUNDS[n])) for n, v in zip(names, x, strict=True)}
    return spec_with(cfg, th), fun


def pooled(per_flight: dict[str, dict]) -> dict[str, float]:
    """Sample-weighted mean of per-flight held-out statistics."""
    w = np.array([r["n"] for r in per_flight.values()], dtype=float)
    return {
        s: float(np.average([r[s] for r in per_flight.values()], weights=w))
        for s in ("median_abs_db", "p90_abs_db", "rms_db", "soft_l1")
    }


def leave_one_group_out(
    cfg: dict, flights: Sequence[FlightSamples], groups: Sequence[str], **kw
) -> dict:
    """Fit on all groups but one, score the held-out group's flights; -> {"folds", "per_flight",
    "pooled"}."""
    folds, per_flight = {}, {}
    for g in sorted(set(groups)):
        train = [f for f, gg in zip(flights, groups, strict=True) if gg != g]
        test = [f for f, gg in zip(flights, groups, strict=True) if gg == g]
        if not train:
            raise InputError(
                "held-out calibration needs flights of at least two groups", field="--groups"
            )
        spec, _ = fit_config(cfg, train, **kw)
        m = build_model(spec)
        folds[f"without-{g}"] = {
            "fitted_on": [f.name for f in train],
            "tested_on": [f.name for f in test],
            "model": spec,
        }
        for f in test:
            per_flight[f.name] = gap_stats(m, f)
    return {"folds": folds, "per_flight": per_flight, "pooled": pooled(per_flight)}


def calibrate(
    flights: Sequence[FlightSamples],
    groups: Sequence[str],
    configs: Sequence[str] = DEFAULT_CONFIGS,
    progress: Callable[[str], None] | None = None,
    **kw,
) -> dict:
    """Held-out comparison of ``configs`` and the chosen one refitted on all flights
    (``preset_record`` input)."""
    if len(flights) != len(groups):
        raise InputError("one group per flight is needed")
    rows = {}
    for name in configs:
        if progress:
            progress(name)
        rows[name] = leave_one_group_out(config(name), flights, groups, **kw)
    choose = min(rows, key=lambda k: rows[k]["pooled"]["soft_l1"])
    spec, train_loss = fit_config(config(choose), flights, **kw)
    return {"configs": rows, "chosen": choose, "model": spec, "train_soft_l1": train_loss}


def preset_record(
    name: str,
    result: dict,
    flights: Sequence[FlightSamples],
    groups: Sequence[str],
    command: str,
    data: str = "",
) -> dict:
    """A preset file (``mission.physics.presets`` record): model, what it was fitted on, folds,
    held-out figures."""
    ch = result["configs"][result["chosen"]]
    return {
        "name": name,
        "description": f"Propagation model calibrated with `rfsl calibrate` on {len(flights)} "
        "flights "
        f"(per-flight free offset, {LOSS} loss, f_scale {F_SCALE_DB:g} dB), chosen by the lowest "
        "leave-one-group-out soft-L1",
        "model": result["model"],
        "config": result["chosen"],
        "fitted_on": [f.name for f in flights],
        "groups": dict(zip([f.name for f in flights], groups, strict=True)),
        "folds": ch["folds"],
        "heldout_gap": ch["pooled"],
        "heldout_gap_per_flight": ch["per_flight"],
        "heldout_gap_by_config": {k: v["pooled"] for k, v in result["configs"].items()},
        "data": data,
        "command": command,
        "date": datetime.date.today().isoformat(),
    }
