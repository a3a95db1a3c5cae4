"""Is a flight inside a network's training domain?  Its cruise altitude and attitude against the
training's, and how much of its planned track it flew.

Why: a network learns the RSS contrast of the altitude it was trained at.  ``rfsl_spiral_e2r`` (the
network half of the real-log default, trained at 30 m only) has a 7.4 m mean error on simulated
spirals at 30 m, 13.8 / 14.2 m at 25 / 35 m, 22.9 m at 40 m and 28.8 / 40.7 m at 20 / 47 m
(models/README.md, the altitude-robust spiral network); teams fly at 20-47 m.  ``localize``
therefore says when a flight is more than ``ALTITUDE_TOLERANCE_M`` (where the simulated error has
doubled) outside the range a network was trained on, instead of silently averaging its answer in.
The training's spans are the network's card's (``card.TrainingDomain``, measured at training time by
``mission.workshop.domain``).
"""

from __future__ import annotations

import numpy as np

from mission.defaults import DEFAULT_ALTITUDE_M
from mission.errors import InputError
from mission.geo import afar_field
from mission.trajectory.generators import generate

ALTITUDE_TOLERANCE_M = (
    5.0  # 5 m off its training altitude the spiral network's simulated error doubles
)
ATTITUDE_TOLERANCE_DEG = (
    5.0  # flown roll / pitch (5-95 %) may leave the training's 1-99 % span by this much
)
# on a simulated log a network's error circles apply only inside its training attitudes, with no
# tolerance: they were calibrated on simulated flights of the training's kind, and on ArduCopter
# SITL (2 deg past the span) the 90 % circle held 1 of 10 fresh flights; the posterior's regions
# that replace them held 10 of 10 (benchmarks/score_sim_circles.py; models/README.md)
CIRCLE_ATTITUDE_TOLERANCE_DEG = 0.0
# a planned point counts as flown when a used sample passed this close (spiral rings: 22 m)
TRACK_REACH_M = 10.0
TRACK_STEP_M = 5.0  # the planned track is checked every 5 m of its length


def flight_altitudes(z_m: np.ndarray) -> tuple[float, float]:
    """The altitude span of the samples a localizer used: 10th and 90th percentile of their heights
    (m)."""
    lo, hi = np.percentile(np.asarray(z_m, dtype=float), [10.0, 90.0])
    return float(lo), float(hi)


def altitude_note(
    model_name: str,
    trained: tuple[float, float] | None,
    flown: tuple[float, float],
    tolerance_m: float = ALTITUDE_TOLERANCE_M,
) -> str | None:
    """A one-sentence note when the flown altitudes leave the trained range by more than
    ``tolerance_m``."""
    if trained is None:
        return None
    off = max(trained[0] - flown[0], flown[1] - trained[1])
    if off <= tolerance_m:
        return None
    t = (
        f"{trained[0]:.0f} m"
        if trained[0] == trained[1]
        else f"{trained[0]:.0f}-{trained[1]:.0f} m"
    )
    f = (
        f"{flown[0]:.0f} m"
        if round(flown[0]) == round(flown[1])
        else f"{flown[0]:.0f}-{flown[1]:.0f} m"
    )
    return (
        f"{model_name} was trained on flights at {t}; this one flew at {f}, {off:.0f} m "
        "outside that: networks "
        "lose accuracy off their training altitude (in simulation the shipped spiral network's "
        "error doubles 5 m "
        "off and grows 3-5x 10-17 m off, models/README.md), so its half of the estimate is "
        "less reliable"
    )


def trained_legs(part):
    """The samples a network was trained on: all but the transit to the first waypoint
    (``mission_item`` 0).

    Why: training sets fly the trajectory only (``DatasetConfig.cruise_only``), while a logged
    mission also holds the transit from the top of the climb to the first waypoint (``mission_item``
    0).  On ``rfsl simulate`` spirals at 30 m that leg cost the spiral ensemble 4.3 -> 5.1 m median
    (benchmarks/sim_default.py).  Logs without the column, or whose mission never reached the first
    waypoint, are returned unchanged."""
    item = part.columns.get("mission_item")
    if item is None:
        return part
    keep = np.asarray(item, dtype=float) != 0
    return part if keep.all() or keep.sum() < 2 else part.select(keep)


def planned_track(meta: dict, origin) -> np.ndarray | None:
    """The mission's planned trajectory (K, 2) in the log's frame, from the sidecar's record
    (generator, parameters, altitude) over the AFAR field; None when the sidecar records no
    generated trajectory or the log is not in the AFAR field's frame (a custom field: its plan
    cannot be rebuilt from the record)."""
    traj = meta.get("trajectory") or {}
    field = afar_field()
    if not traj.get("generator") or not _same_origin(origin, field.origin):
        return None
    try:
        w = generate(
            traj["generator"],
            field,
            float(traj.get("altitude_m", DEFAULT_ALTITUDE_M)),
            **(traj.get("params") or {}),
        )
    except (InputError, TypeError, ValueError):
        return None
    lat, lon, _ = field.origin.to_geodetic(np.asarray(w, dtype=float))
    return np.asarray(origin.to_enu(lat, lon))[..., :2]


def _same_origin(a, b) -> bool:
    """Whether two ``Origin`` s are the same point (to a millimetre)."""
    return bool(np.allclose(a.to_enu(b.lat_deg, b.lon_deg, b.alt_m), 0.0, atol=1e-3))


def track_coverage(
    planned_xy: np.ndarray,
    flown_xy: np.ndarray,
    reach_m: float = TRACK_REACH_M,
    step_m: float = TRACK_STEP_M,
) -> float:
    """Share of the planned track (every ``step_m`` along it) that a flown sample passed within
    ``reach_m`` of: 1 for a full flight, about a third for a flight aborted a third of the way."""
    w = np.asarray(planned_xy, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(w, axis=0).T))])
    at = np.linspace(0.0, s[-1], max(int(s[-1] / step_m) + 1, 2))
    pts = np.column_stack([np.interp(at, s, w[:, 0]), np.interp(at, s, w[:, 1])])
    # scipy.spatial stays lazy (noqa): only the calibrated circles' coverage strata need it
    from scipy.spatial import cKDTree  # noqa: PLC0415

    d, _ = cKDTree(np.asarray(flown_xy, dtype=float)).query(pts, distance_upper_bound=reach_m)
    return float(np.mean(np.isfinite(d)))


def flight_attitude(part) -> tuple[tuple[float, float], tuple[float, float]]:
    """((roll 5 %, 95 %), (pitch 5 %, 95 %)) in degrees over the samples a localizer used."""
    r = np.percentile(np.asarray(part["roll_deg"], dtype=float), [5.0, 95.0])
    p = np.percentile(np.asarray(part["pitch_deg"], dtype=float), [5.0, 95.0])
    return (float(r[0]), float(r[1])), (float(p[0]), float(p[1]))


def attitude_note(
    model_name: str, trained, flown, tolerance_deg: float = ATTITUDE_TOLERANCE_DEG
) -> str | None:
    """A one-sentence note when the flown roll or pitch leaves the trained span by more than
    ``tolerance_deg``."""
    if trained is None:
        return None
    out = []
    for what, (tlo, thi), (flo, fhi) in zip(("roll", "pitch"), trained, flown, strict=True):
        if tlo - flo > tolerance_deg or fhi - thi > tolerance_deg:
            out.append(f"{what} {flo:.0f} to {fhi:.0f} deg against {tlo:.0f} to {thi:.0f} deg")
    if not out:
        return None
    return (
        f"this flight's attitude is outside {model_name}'s training domain ({'; '.join(out)}, "
        "5-95 % of the "
        "samples used against the training flights' 1-99 %): the network never saw RSS at "
        "these tilts"
    )


def flown_domain(
    part, trained_attitude, model_name: str, tolerance_deg: float = ATTITUDE_TOLERANCE_DEG
) -> dict:
    """What was flown against a network's training: ``track_coverage`` (share of the planned track
    flown, None without a plan in the sidecar) and ``attitude_note`` (None inside the training's
    attitudes widened by ``tolerance_deg``, ``trained_attitude`` from its card, or when
    unknown)."""
    plan = planned_track(part.meta, part.origin)
    cov = None if plan is None or len(part) < 2 else track_coverage(plan, part.enu()[:, :2])
    return {
        "track_coverage": cov,
        "attitude_note": attitude_note(
            model_name, trained_attitude, flight_attitude(part), tolerance_deg
        ),
    }
