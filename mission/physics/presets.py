"""Physics presets: propagation models calibrated on real flights, shipped as data.

A preset is a JSON file ``mission/data/<name>_calibration.json`` whose ``"model"`` block is a *model
spec* (below); the rest of the file records how it was obtained (flights fitted on, held-out
figures, command, date).  ``preset_model("afar")`` builds the model; ``load_preset("afar")`` returns
the spec (a dict) and ``load_calibration("afar")`` the whole record.

Model spec (every key optional except ``base``)::

    {"base": "free-space",            # make_model name: free-space | two-ray | e2r
     "tx_pattern": "isotropic",       # isotropic | dipole | measured | a file path
     "tx_flipped": false, "tx_heading_deg": 0.0,
     "rx_pattern": "measured", "rx_flipped": true, "rx_heading_deg": 0.0,
     "ground": null,                  # or {"eps_r": 15, "sigma_s_m": 0.005}: adds/overrides the
                                      # reflected ray
     "attitude": true,                # receiver gains in the body frame (roll, pitch, yaw of the
                                      # log);
                                      # "yaw": heading only (body level); false: level, nose north
     "leg_shadowing_beta": null,      # or beta: paper eqs. 8-9 (removed when null)
     "path_gain_slope": 0.0}          # n_extra of PathGainSlope (-10 n_extra log10 d); 0 = none

Why a spec and not ``make_model`` keywords: the calibrated effect list (e.g. free space + measured
upside-down UAV antenna + attitude + a path-gain slope, no ground ray) is not one of the three named
models, and a spec says exactly which effects are present.  ``make_model`` is unchanged.

With the grid search: ``ModelGridSearch(preset_model("afar"))`` (or ``localize_log(...,
physics_model=preset_model("afar"))``).
"""

from __future__ import annotations

import json
import math
from importlib import resources
from typing import Any

from mission.errors import InputError
from mission.fields import REQUIRED, Fields
from mission.files import read_text
from mission.physics.propagation import (
    Attitude,
    GroundReflection,
    LegShadowing,
    PathGainSlope,
    PropagationModel,
    make_model,
)

PRESETS = ("afar",)
SPEC_KEYS = (
    "base",
    "tx_pattern",
    "tx_flipped",
    "tx_heading_deg",
    "rx_pattern",
    "rx_flipped",
    "rx_heading_deg",
    "ground",
    "attitude",
    "leg_shadowing_beta",
    "path_gain_slope",
    "pt_dbm",
    "fc_hz",
)


def build_model(spec: dict[str, Any], name: str = "calibrated") -> PropagationModel:
    """A ``PropagationModel`` from a model spec (module docstring); unknown keys raise
    ValueError."""
    bad = sorted(set(spec) - set(SPEC_KEYS))
    if bad:
        raise ValueError(f"unknown model spec keys {bad} (known: {', '.join(SPEC_KEYS)})")
    kw: dict[str, Any] = {}
    for k in ("pt_dbm", "fc_hz"):
        if k in spec:
            kw[k] = float(spec[k])
    m = make_model(
        spec.get("base", "free-space"),
        pattern="isotropic",
        tx_pattern=spec.get("tx_pattern", "isotropic"),
        rx_pattern=spec.get("rx_pattern", "isotropic"),
        tx_flipped=bool(spec.get("tx_flipped", False)),
        rx_flipped=bool(spec.get("rx_flipped", False)),
        tx_heading_rad=math.radians(float(spec.get("tx_heading_deg", 0.0))),
        rx_heading_rad=math.radians(float(spec.get("rx_heading_deg", 0.0))),
        **kw,
    )
    if "ground" in spec:
        g = spec["ground"]
        m = m.without("ground_reflection") if (g is None and m.has("ground_reflection")) else m
        if g is not None:
            m = m.with_effect(
                GroundReflection(
                    eps_r=float(g.get("eps_r", 2.0)),
                    sigma_s_m=float(g.get("sigma_s_m", 0.0)),
                    polarization=str(g.get("polarization", "V")),
                )
            )
    if "attitude" in spec:
        if spec["attitude"] == "yaw":
            m = m.with_effect(Attitude(roll_pitch=False))
        elif spec["attitude"]:
            m = m.with_effect(Attitude())
        elif m.has("attitude"):
            m = m.without("attitude")
    if "leg_shadowing_beta" in spec:
        b = spec["leg_shadowing_beta"]
        if b is None:
            m = m.without("leg_shadowing") if m.has("leg_shadowing") else m
        else:
            m = m.with_effect(LegShadowing(beta=float(b)))
    n = float(spec.get("path_gain_slope", 0.0) or 0.0)
    if n != 0.0:
        m = m.with_effect(PathGainSlope(n_extra=n))
    return PropagationModel(m.effects, name=name, dtype=m.dtype)


def load_calibration(name: str = "afar") -> dict[str, Any]:
    """The whole calibration record of preset ``name`` (the JSON file as a dict); a path ending in
    ``.json`` reads a preset file written by ``rfsl calibrate``."""
    base = (
        name.strip().partition(":")[0]
        if not name.strip().lower().endswith(".json")
        else name.strip()
    )
    if base.lower().endswith(".json"):  # a preset written by ``rfsl calibrate --out FILE.json``
        try:
            rec = json.loads(
                read_text(base, "physics preset file", "--physics-preset", max_bytes=10_000_000)
            )
        except (ValueError, RecursionError) as e:
            if isinstance(e, InputError):
                raise
            raise InputError(
                f"cannot read physics preset file: {str(e)[:120]}", source=base
            ) from None
        Fields(rec, base, shape="a physics preset (a JSON object)").sub("model", REQUIRED)
        return rec
    key = base.lower()
    if key not in PRESETS:
        raise InputError(
            f"unknown physics preset {name!r} (known: {', '.join(PRESETS)})", field="preset"
        )
    ref = resources.files("mission").joinpath("data", f"{key}_calibration.json")
    try:
        return json.loads(ref.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        raise InputError(f"cannot read physics preset {key!r}: {e}", source=str(ref)) from None


def load_preset(name: str = "afar") -> dict[str, Any]:
    """The model spec of preset ``name`` (a dict for :func:`build_model`).

    ``"afar:FOLD"`` is the spec fitted on one fold of the calibration only (``folds`` in the record,
    e.g. ``afar:fit328`` = fitted on team 328's flights): train or test with it on the *other*
    flights so that nothing is scored on the flights its physics was fitted on.
    """
    base, _, fold = name.rpartition(":") if ".json:" in name.lower() else name.partition(":")
    rec = load_calibration(base)
    if not fold:
        return dict(rec["model"])
    folds = rec.get("folds", {})
    if fold not in folds:
        raise InputError(
            f"physics preset {base!r} has no fold {fold!r} (known: {', '.join(folds)})",
            field="preset",
        )
    return dict(folds[fold]["model"])


def preset_model(name: str = "afar", **overrides: Any) -> PropagationModel:
    """The calibrated model of preset ``name``; ``overrides`` replace spec entries (e.g.
    ``attitude=False``)."""
    spec = {**load_preset(name), **overrides}
    return build_model(spec, name=f"{name.strip().lower().replace(':', '-')}-calibrated")
