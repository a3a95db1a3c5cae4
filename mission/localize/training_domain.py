"""Is a flight inside a network's training domain?  Today: its cruise altitude against the altitudes trained on.

Why: a network learns the RSS contrast of the altitude it was trained at.  ``rfsl_spiral_e2r`` (the network
half of the real-log default, trained at 30 m only) has a 7.4 m mean error on simulated spirals at 30 m, 13.8 /
14.2 m at 25 / 35 m, 22.9 m at 40 m and 28.8 / 40.7 m at 20 / 47 m (models/README.md, stop 18); teams fly at
20-47 m.  ``localize`` therefore says when a flight is more than ``ALTITUDE_TOLERANCE_M`` (where the simulated
error has doubled) outside the range a network was trained on, instead of silently averaging its answer in.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from mission.errors import InputError

ALTITUDE_TOLERANCE_M = 5.0  # 5 m off its training altitude the spiral network's simulated error doubles


@lru_cache(maxsize=32)
def _mission_altitude(mission: str) -> float | None:
    """Cruise altitude (m) of a training mission named by path (as the dataset recorded it; tried as given and
    relative to the repository), or None when the file is not here or not a mission.  Cached: a network's
    datasets usually name one mission, and parsing its YAML on every ``localize`` call cost ~8 ms."""
    from mission.spec import DEFAULT_MISSION, load_mission

    for p in (Path(mission), DEFAULT_MISSION.parents[1] / mission):  # as given, or in this checkout
        if p.is_file():
            try:
                return float(load_mission(p).altitude_m)
            except InputError:
                return None
    return None


def _dataset_altitudes(d: dict) -> tuple[float, float] | None:
    """Altitude range (m) of one training dataset's flights from its metadata entry, or None if unknown."""
    rnd = d.get("randomisation") or {}
    if rnd.get("altitude_m"):
        lo, hi = rnd["altitude_m"]
        return float(lo), float(hi)
    if str(d.get("model", "")).startswith("suite:"):
        from mission.localize.suite import ALTITUDE_RANGE_M

        return ALTITUDE_RANGE_M
    alt = d.get("mission_altitude_m")
    if alt is None and d.get("mission"):
        alt = _mission_altitude(str(d["mission"]))
    return None if alt is None else (float(alt), float(alt))


def training_altitudes(meta: dict) -> tuple[float, float] | None:
    """Cruise altitude range (m) covered by a network's training flights (the union over its datasets), from the
    ONNX metadata's ``training_data``; None when any dataset's altitude is unknown (no claim is better than a
    wrong one)."""
    datasets = (meta.get("training_data") or {}).get("datasets") or []
    ranges = [_dataset_altitudes(d) for d in datasets]
    if not ranges or any(r is None for r in ranges):
        return None
    return min(r[0] for r in ranges), max(r[1] for r in ranges)


def flight_altitudes(z_m: np.ndarray) -> tuple[float, float]:
    """The altitude span of the samples a localizer used: 10th and 90th percentile of their heights (m)."""
    lo, hi = np.percentile(np.asarray(z_m, dtype=float), [10.0, 90.0])
    return float(lo), float(hi)


def altitude_note(model_name: str, trained: tuple[float, float] | None, flown: tuple[float, float],
                  tolerance_m: float = ALTITUDE_TOLERANCE_M) -> str | None:
    """A one-sentence note when the flown altitudes leave the trained range by more than ``tolerance_m``."""
    if trained is None:
        return None
    off = max(trained[0] - flown[0], flown[1] - trained[1])
    if off <= tolerance_m:
        return None
    t = f"{trained[0]:.0f} m" if trained[0] == trained[1] else f"{trained[0]:.0f}-{trained[1]:.0f} m"
    f = f"{flown[0]:.0f} m" if round(flown[0]) == round(flown[1]) else f"{flown[0]:.0f}-{flown[1]:.0f} m"
    return (f"{model_name} was trained on flights at {t}; this one flew at {f}, {off:.0f} m outside that: networks "
            "lose accuracy off their training altitude (in simulation the shipped spiral network's error doubles 5 m "
            "off and grows 3-5x 10-17 m off, models/README.md), so its half of the estimate is less reliable")
