"""A network's training domain, measured once at training time and written into its card: the cruise
altitude span and the roll / pitch spans of its training flights
(``mission.localize.card.TrainingDomain``).

Why here: the spans come from the training datasets' records (their mission files, randomisation)
and, for the attitude, from the simulator flying the training mission; the runtime reads the numbers
from the card and never parses a mission or runs the simulator.  ``rfsl train`` and
``models/write_card_json.py`` call ``write_domain``.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from mission.adaptive.planner import flown_ahead
from mission.errors import InputError
from mission.localize.card import DOMAIN_KEY, TrainingDomain, card_path
from mission.simulate import fly_path
from mission.spec import DEFAULT_MISSION, load_mission
from mission.workshop.suite import ALTITUDE_RANGE_M as SUITE_ALTITUDE_RANGE_M


def _mission_file(mission: str) -> Path | None:
    """A training mission named by path (as the dataset recorded it): as given, or relative to the
    repository."""
    for p in (Path(mission), DEFAULT_MISSION.parents[1] / mission):
        if p.is_file():
            return p
    return None


def _mission_altitude(mission: str) -> float | None:
    """Cruise altitude (m) of a training mission, or None when the file is not here or not a
    mission."""
    p = _mission_file(mission)
    try:
        return None if p is None else float(load_mission(p).altitude_m)
    except InputError:
        return None


def _dataset_altitudes(d: dict) -> tuple[float, float] | None:
    """Altitude range (m) of one training dataset's flights from its metadata entry, or None if
    unknown."""
    rnd = d.get("randomisation") or {}
    if rnd.get("altitude_m"):
        lo, hi = rnd["altitude_m"]
        return float(lo), float(hi)
    if str(d.get("model", "")).startswith("suite:"):
        return SUITE_ALTITUDE_RANGE_M
    alt = d.get("mission_altitude_m")
    if alt is None and d.get("mission"):
        alt = _mission_altitude(str(d["mission"]))
    return None if alt is None else (float(alt), float(alt))


def training_altitudes(training_data: dict | None) -> tuple[float, float] | None:
    """Cruise altitude range (m) covered by a network's training flights (the union over its
    datasets), from its ``training_data`` metadata; None when any dataset's altitude is unknown (no
    claim is better than a wrong one)."""
    datasets = (training_data or {}).get("datasets") or []
    ranges = [_dataset_altitudes(d) for d in datasets]
    if not ranges or any(r is None for r in ranges):
        return None
    return min(r[0] for r in ranges), max(r[1] for r in ranges)


def _mission_attitude(
    mission: str, drag_pitch_deg_per_mps: float | None = None
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """(roll, pitch) 1-99 % spans (deg) of the simulator flying a training mission's trajectory with
    its own kinematics (``drag_pitch_deg_per_mps`` replacing its nose-down pitch when given) and
    perturbation (seed 0), as ``rfsl dataset`` flies it; None when the mission is not here."""
    p = _mission_file(mission)
    if p is None:
        return None
    try:
        spec = flown_ahead(load_mission(p))
    except InputError:
        return None
    # percentiles of a 0.2 s sampling: 10x cheaper, same spans
    cfg = replace(spec.sim_config(), dt_s=0.2)
    if drag_pitch_deg_per_mps is not None:
        kin = replace(cfg.kinematics, drag_pitch_deg_per_mps=drag_pitch_deg_per_mps)
        cfg = replace(cfg, kinematics=kin)
    _, _, att, _ = fly_path(spec.waypoints_enu(), cfg, np.random.default_rng(0))
    deg = np.rad2deg(att[:, :2])
    r, q = (np.percentile(deg[:, k], [1.0, 99.0]) for k in (0, 1))
    return (float(r[0]), float(r[1])), (float(q[0]), float(q[1]))


def training_attitude(
    training_data: dict | None,
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """(roll, pitch) spans (deg) of a network's training flights (union over its datasets): known
    for datasets that flew one mission's trajectory with its kinematics; None when any dataset drew
    trajectories, speeds or headings at random or has no mission here (no claim is better than a
    wrong one)."""
    spans = []
    for d in (training_data or {}).get("datasets") or []:
        rnd = d.get("randomisation") or {}
        if (
            not d.get("mission")
            or rnd.get("trajectories")
            or rnd.get("random_params")
            or rnd.get("speed_mps")
            or rnd.get("random_heading")
        ):
            return None
        # a drawn nose-down pitch: the mission flown at both ends of its range (the span is
        # monotone in it)
        drags = rnd.get("drag_pitch_deg_per_mps") or [None]
        for drag in drags:
            span = _mission_attitude(str(d["mission"]), drag)
            if span is None:
                return None
            spans.append(span)
    if not spans:
        return None
    lo_hi = ((min(s[k][0] for s in spans), max(s[k][1] for s in spans)) for k in (0, 1))
    return tuple(lo_hi)  # type: ignore


def training_domain(training_data: dict | None) -> TrainingDomain:
    """The card's training domain of a network with this ``training_data`` metadata."""
    return TrainingDomain(training_altitudes(training_data), training_attitude(training_data))


def write_domain(model_path: str | Path, training_data: dict | None) -> TrainingDomain:
    """Measure the training domain and write it into the card beside ``model_path`` (created when
    absent; its other keys kept)."""
    dom = training_domain(training_data)
    p = card_path(model_path)
    card = json.loads(p.read_text()) if p.is_file() else {"model": Path(model_path).name}
    card[DOMAIN_KEY] = dom.to_dict()
    p.write_text(json.dumps(card, indent=1) + "\n")
    return dom
