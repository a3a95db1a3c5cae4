"""Is a flight inside a network's training domain?  Its cruise altitude and attitude against the training's, and
how much of its planned track it flew.

Why: a network learns the RSS contrast of the altitude it was trained at.  ``rfsl_spiral_e2r`` (the network
half of the real-log default, trained at 30 m only) has a 7.4 m mean error on simulated spirals at 30 m, 13.8 /
14.2 m at 25 / 35 m, 22.9 m at 40 m and 28.8 / 40.7 m at 20 / 47 m (models/README.md, the altitude-robust
spiral network); teams fly at 20-47 m.  ``localize`` therefore says when a flight is more than
``ALTITUDE_TOLERANCE_M`` (where the simulated error has doubled) outside the range a network was trained on,
instead of silently averaging its answer in.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from mission.errors import InputError

ALTITUDE_TOLERANCE_M = 5.0  # 5 m off its training altitude the spiral network's simulated error doubles
ATTITUDE_TOLERANCE_DEG = 5.0  # flown roll / pitch (5-95 %) may leave the training's 1-99 % span by this much
TRACK_REACH_M = 10.0  # a planned point counts as flown when a used sample passed this close (spiral rings: 22 m)
TRACK_STEP_M = 5.0  # the planned track is checked every 5 m of its length
# cruise altitude the unseen-flight benchmark draws per flight (mission.workshop.suite): a network trained on
# "suite:" data reports this range
SUITE_ALTITUDE_RANGE_M = (15.0, 60.0)


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
        return SUITE_ALTITUDE_RANGE_M
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


def trained_legs(part):
    """The samples a network was trained on: all but the transit to the first waypoint (``mission_item`` 0).

    Why: training sets fly the trajectory only (``DatasetConfig.cruise_only``), while a logged mission also holds
    the transit from the top of the climb to the first waypoint (``mission_item`` 0).  On ``rfsl simulate``
    spirals at 30 m that leg cost the spiral ensemble 4.3 -> 5.1 m median (benchmarks/sim_default.py).  Logs
    without the column, or whose mission never reached the first waypoint, are returned unchanged."""
    item = part.columns.get("mission_item")
    if item is None:
        return part
    keep = np.asarray(item, dtype=float) != 0
    return part if keep.all() or keep.sum() < 2 else part.select(keep)


def planned_track(meta: dict, origin) -> np.ndarray | None:
    """The mission's planned trajectory (K, 2) in the log's frame, from the sidecar: the mission file it names
    when that file is here and still plans the recorded trajectory, else the recorded trajectory (generator,
    parameters, altitude) over the AFAR field; None when the sidecar records no trajectory."""
    from mission.geo import afar_field
    from mission.spec import MissionSpec, load_mission
    from mission.trajectory.generators import generate

    traj = meta.get("trajectory") or {}
    if not traj.get("generator"):
        return None
    w, frame = None, afar_field().origin
    for key in ("mission_file", "mission"):
        p = meta.get(key)
        if isinstance(p, str) and Path(p).is_file():
            try:
                spec = load_mission(p)
                if spec.trajectory_meta() == traj:
                    w, frame = spec.waypoints_enu(), spec.field.origin
                    break
            except InputError:
                continue
    if w is None:
        try:
            w = generate(traj["generator"], afar_field(), float(traj.get("altitude_m", MissionSpec.altitude_m)),
                         **(traj.get("params") or {}))
        except (InputError, TypeError, ValueError):
            return None
    lat, lon, _ = frame.to_geodetic(np.asarray(w, dtype=float))
    return np.asarray(origin.to_enu(lat, lon))[..., :2]


def track_coverage(planned_xy: np.ndarray, flown_xy: np.ndarray, reach_m: float = TRACK_REACH_M,
                   step_m: float = TRACK_STEP_M) -> float:
    """Share of the planned track (every ``step_m`` along it) that a flown sample passed within ``reach_m`` of:
    1 for a full flight, about a third for a flight aborted a third of the way."""
    from scipy.spatial import cKDTree

    w = np.asarray(planned_xy, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(w, axis=0).T))])
    at = np.linspace(0.0, s[-1], max(int(s[-1] / step_m) + 1, 2))
    pts = np.column_stack([np.interp(at, s, w[:, 0]), np.interp(at, s, w[:, 1])])
    d, _ = cKDTree(np.asarray(flown_xy, dtype=float)).query(pts, distance_upper_bound=reach_m)
    return float(np.mean(np.isfinite(d)))


def flight_attitude(part) -> tuple[tuple[float, float], tuple[float, float]]:
    """((roll 5 %, 95 %), (pitch 5 %, 95 %)) in degrees over the samples a localizer used."""
    r = np.percentile(np.asarray(part["roll_deg"], dtype=float), [5.0, 95.0])
    p = np.percentile(np.asarray(part["pitch_deg"], dtype=float), [5.0, 95.0])
    return (float(r[0]), float(r[1])), (float(p[0]), float(p[1]))


@lru_cache(maxsize=32)
def _mission_attitude(mission: str) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """(roll, pitch) 1-99 % spans (deg) of the simulator flying a training mission's trajectory with its own
    kinematics and perturbation (seed 0), as ``rfsl dataset`` flies it; None when the mission is not here."""
    from mission.simulate import fly_path
    from mission.spec import DEFAULT_MISSION, load_mission

    for p in (Path(mission), DEFAULT_MISSION.parents[1] / mission):
        if p.is_file():
            try:
                spec = load_mission(p)
            except InputError:
                return None
            cfg = replace(spec.sim_config(), dt_s=0.2)  # percentiles of a 0.2 s sampling: 10x cheaper, same spans
            _, _, att, _ = fly_path(spec.waypoints_enu(), cfg, np.random.default_rng(0))
            deg = np.rad2deg(att[:, :2])
            r, q = (np.percentile(deg[:, k], [1.0, 99.0]) for k in (0, 1))
            return (float(r[0]), float(r[1])), (float(q[0]), float(q[1]))
    return None


def training_attitude(meta: dict) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """(roll, pitch) spans (deg) of a network's training flights (union over its datasets): known for datasets
    that flew one mission's trajectory with its kinematics; None when any dataset drew trajectories, speeds or
    headings at random or has no mission here (no claim is better than a wrong one)."""
    spans = []
    for d in (meta.get("training_data") or {}).get("datasets") or []:
        rnd = d.get("randomisation") or {}
        if not d.get("mission") or rnd.get("trajectories") or rnd.get("random_params") or rnd.get("speed_mps") \
                or rnd.get("random_heading"):
            return None
        span = _mission_attitude(str(d["mission"]))
        if span is None:
            return None
        spans.append(span)
    if not spans:
        return None
    return tuple((min(s[k][0] for s in spans), max(s[k][1] for s in spans)) for k in (0, 1))  # type: ignore


def attitude_note(model_name: str, trained, flown, tolerance_deg: float = ATTITUDE_TOLERANCE_DEG) -> str | None:
    """A one-sentence note when the flown roll or pitch leaves the trained span by more than ``tolerance_deg``."""
    if trained is None:
        return None
    out = []
    for what, (tlo, thi), (flo, fhi) in zip(("roll", "pitch"), trained, flown, strict=True):
        if tlo - flo > tolerance_deg or fhi - thi > tolerance_deg:
            out.append(f"{what} {flo:.0f} to {fhi:.0f} deg against {tlo:.0f} to {thi:.0f} deg")
    if not out:
        return None
    return (f"this flight's attitude is outside {model_name}'s training domain ({'; '.join(out)}, 5-95 % of the "
            "samples used against the training flights' 1-99 %): the network never saw RSS at these tilts")


def flown_domain(part, net_meta: dict, model_name: str) -> dict:
    """What was flown against a network's training: ``track_coverage`` (share of the planned track flown, None
    without a plan in the sidecar) and ``attitude_note`` (None inside the training's attitudes or when unknown)."""
    plan = planned_track(part.meta, part.origin)
    cov = None if plan is None or len(part) < 2 else track_coverage(plan, part.enu()[:, :2])
    return {"track_coverage": cov,
            "attitude_note": attitude_note(model_name, training_attitude(net_meta), flight_attitude(part))}
