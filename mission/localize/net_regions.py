"""Uncertainty regions for a network's estimate: error circles calibrated by split conformal prediction.

Why: a network answers with a point and no posterior, yet every estimate must carry 50 % and 90 % regions
(issue 10).  Flights like those the network will face, never trained on, give the distribution of its 2D error;
the circle around the estimate whose radius is that error's conformal quantile (the ``ceil((n + 1) level)``-th
smallest of ``n`` calibration errors) holds the truth at the nominal rate or more on any flight exchangeable
with them.  Nothing about the flight at hand narrows the circle: it is honest on average over its calibration
domain and says nothing finer.

Each shipped network's card (``models/<name>.json``, key ``regions``) holds one calibration per kind of log:

- ``sim``: held-out simulated flights of the domain where ``localize`` uses it on simulated logs
  (``benchmarks/calibrate_net_regions.py`` names each set);
- ``real``: the unseen-flight benchmark (``afar`` family, seeds 2027 and 2028), what ``--model`` faces on a
  real receiver's log.

Regions use the layout of :mod:`mission.localize.uncertainty` (``level``, ``hpd_mass``, ``area_m2``,
``ellipse``, ``polygons``) plus ``kind = "error circle"``, ``radius_m`` and ``calibrated_on``.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from mission.errors import InputError

REGIONS_KEY = "regions"
DOMAINS = ("sim", "real")
LEVELS = (0.5, 0.9)
N_VERTICES = 72


def conformal_radius(errors, level: float) -> float:
    """The split-conformal radius: the ``ceil((n + 1) level)``-th smallest error (inf when n is too small)."""
    e = np.sort(np.asarray(errors, dtype=float))
    k = math.ceil((e.size + 1) * float(level))
    return float(e[k - 1]) if 1 <= k <= e.size else float("inf")


def model_digest(model_path: str | Path) -> str:
    """sha256 of a model file: a card's calibration names the exact network it was measured on."""
    return hashlib.sha256(Path(model_path).read_bytes()).hexdigest()


def calibration_record(errors, source: str, model_path: str | Path, levels: tuple[float, ...] = LEVELS) -> dict:
    """What a card stores for one domain: radii per level, the number of flights, where they came from and the
    digest of the model file they were measured on."""
    e = np.asarray(errors, dtype=float)
    radii = {f"{lv:g}": round(conformal_radius(e, lv), 2) for lv in levels}
    if not all(math.isfinite(r) for r in radii.values()):
        raise ValueError(f"{e.size} flights cannot calibrate levels {levels}: need at least "
                         f"{math.ceil(max(levels) / (1 - max(levels)) - 1e-9)}")
    return {"radii_m": radii, "n": int(e.size),
            "mean_error_m": round(float(e.mean()), 2), "calibrated_on": source,
            "model_sha256": model_digest(model_path)}


def card_path(model_path: str | Path) -> Path:
    """The model card beside a network: ``models/<name>.json`` for ``models/<name>.onnx``."""
    return Path(model_path).with_suffix(".json")


def card_calibration(model_path: str | Path, domain: str) -> tuple[dict | None, str | None]:
    """(the card's calibration for ``domain`` ("sim" or "real"), None) or (None, why there is none: no card, no
    entry, or an entry measured on another model file); a malformed entry is an ``InputError`` naming the card
    and key."""
    p = card_path(model_path)
    where = f"{p.name}, benchmarks/calibrate_net_regions.py"
    if not p.is_file():
        return None, f"{Path(model_path).name} has no model card ({where})"
    try:
        rec = (json.loads(p.read_text()).get(REGIONS_KEY) or {}).get(domain)
    except (json.JSONDecodeError, AttributeError):
        raise InputError("model card is not a JSON object with a regions mapping", source=str(p),
                         field=REGIONS_KEY) from None
    if rec is None:
        return None, f"{Path(model_path).name} has no '{domain}' calibration in its card ({where})"
    try:
        radii = {float(k): float(v) for k, v in rec["radii_m"].items()}
    except (KeyError, TypeError, ValueError, AttributeError):
        raise InputError("needs radii_m: {level: metres}", source=str(p), field=f"{REGIONS_KEY}.{domain}") from None
    if not radii or not all(0.0 < k < 1.0 and 0.0 < v < math.inf for k, v in radii.items()):
        raise InputError("radii_m needs levels in (0, 1) and positive finite radii", source=str(p),
                         field=f"{REGIONS_KEY}.{domain}.radii_m")
    if rec.get("model_sha256") != model_digest(model_path):
        return None, f"the '{domain}' calibration in {p.name} was measured on another version of the model file"
    return dict(rec, radii_m=radii), None


def circle_regions(x: float, y: float, radii: dict[float, float], calibrated_on: str) -> list[dict]:
    """Error circles around (x, y) for each level -> radius, in the uncertainty-region layout."""
    t = np.linspace(0.0, 2.0 * np.pi, N_VERTICES + 1)
    out = []
    for lv, r in sorted(radii.items()):
        ring = np.round(np.stack([x + r * np.cos(t), y + r * np.sin(t)], axis=1), 1).tolist()
        out.append({"level": float(lv), "hpd_mass": float(lv), "kind": "error circle", "radius_m": float(r),
                    "area_m2": float(np.pi * r * r),
                    "ellipse": {"x_m": float(x), "y_m": float(y), "a_m": float(r), "b_m": float(r), "angle_deg": 0.0},
                    "polygons": [ring], "calibrated_on": calibrated_on})
    return out


def network_regions(extras: dict, x: float, y: float, model_path: str | Path, simulated: bool) -> str | None:
    """Attach the network's calibrated error circles to ``extras["regions"]`` (log frame, around (x, y)) for a
    simulated or a real log; returns a note when its card has no calibration for that kind of log."""
    rec, why = card_calibration(model_path, "sim" if simulated else "real")
    if rec is None:
        return f"no uncertainty region: {why}"
    extras["regions"] = circle_regions(x, y, rec["radii_m"], str(rec.get("calibrated_on", "")))
    return None
