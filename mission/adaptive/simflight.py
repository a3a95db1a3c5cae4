"""Fixed and adaptive flights on the fast simulator under a physics family (benchmark and preview).

Why here and not MAVLink: hundreds of flights in minutes.  The adaptive flight follows the runner's
order of events: the survey, then rounds planned ``lead_s`` before the current one ends from the
estimate of the samples logged so far (``methods.ADAPTIVE_METHOD``'s estimator), each checked by
``planner.plan_round``; stop when the 90 % region is below target or no round fits; return home.
One flight's physics (model draw, offset, transmitter and one fixed shadowing map) is shared by its
fixed and adaptive versions, so they are paired.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from mission.adaptive.planner import plan_round, round_target, survey_profile
from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.flight.live import summary
from mission.flightlog import (
    ADAPTIVE,
    FLOWN_PHASES,
    LAND,
    MISSION,
    RETURN,
    TAKEOFF,
    FlightLog,
    make_meta,
)
from mission.localize.api import localize_log, make_localizer
from mission.localize.methods import ADAPTIVE_METHOD
from mission.localize.uncertainty import region_covers
from mission.physics.family import FamilyDraw
from mission.physics.shadowing import draw_shadowing
from mission.samples import FlightSamples
from mission.simulate import SimConfig, fly_path
from mission.trajectory.autopilot import ReturnModel

MISSION_PHYSICS = "mission"  # the family name that means the mission's own source model


def mission_draw(spec) -> FamilyDraw:
    """The physics ``fly-mission`` simulates for ``spec`` as a family draw: its source model (built
    by ``spec.propagation_model``), its white noise, no offset and no shadowing."""
    return FamilyDraw(
        spec={},
        shadowing_db=0.0,
        shadowing_corr_m=1.0,
        noise_db=spec.source.noise_db,
        offset_db=0.0,
    )


class FlightWorld:
    """One flight's physics: a family draw (``family`` None: the mission's own source model,
    ``mission_draw``), its transmitter and a shadowing map fixed over the flight area."""

    def __init__(self, spec, family, rng: np.random.Generator, step_m: float = 3.0) -> None:

        if family is None:
            self.draw, self.model = mission_draw(spec), spec.propagation_model()
        else:
            self.draw = family.draw(rng)
            self.model = self.draw.model()
        if self.draw.shadowing_over != "ground":  # its map is fixed over the area before flying
            raise InputError(
                "the fast simulator draws shadowing fixed to the ground; this family draws it "
                f"along the path ({family.name})",
                field="shadowing_over",
            )
        self.tx = spec.resolve_tx(rng)
        v = spec.field.flight_area.vertices
        xs = np.arange(v[:, 0].min() - 30, v[:, 0].max() + 30 + step_m, step_m)
        ys = np.arange(v[:, 1].min() - 30, v[:, 1].max() + 30 + step_m, step_m)
        g = np.stack(np.meshgrid(xs, ys, indexing="ij"), -1).reshape(-1, 2)
        sh = draw_shadowing(
            g,
            self.draw.shadowing_db,
            self.draw.shadowing_corr_m,
            "ground",
            rng,
            self.draw.shadowing_marginal,
            self.draw.shadowing_covariance,
        ).reshape(len(xs), len(ys))
        self._shadow = RegularGridInterpolator((xs, ys), sh, bounds_error=False, fill_value=0.0)

    def rss(self, pos: np.ndarray, att: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """RSS (dBm): model + offset + white noise + the flight's shadowing at ``pos``."""
        r = np.asarray(self.model.rss_dbm(self.tx, pos, att), dtype=float) + self.draw.offset_db
        return r + rng.normal(0.0, self.draw.noise_db, r.shape) + self._shadow(pos[:, :2])


@dataclass
class SimLog:
    """Samples of a simulated flight with their phase, appended segment by segment."""

    t: list = field(default_factory=list)
    pos: list = field(default_factory=list)
    att: list = field(default_factory=list)
    rss: list = field(default_factory=list)
    phase: list = field(default_factory=list)
    t_end: float = 0.0

    def fly(self, path, phases, world: FlightWorld, cfg: SimConfig, rng) -> None:
        """Fly ``path`` (K, 3) from the current end; ``phases`` (K-1,) names each leg."""
        t, pos, att, prof = fly_path(np.asarray(path, dtype=float), cfg, rng)
        leg = np.clip(np.searchsorted(prof.t_vertex, t, side="right") - 1, 0, len(path) - 2)
        if self.t:
            t, pos, att = t[1:], pos[1:], att[1:]
            leg = leg[1:]
        self.t.append(t + self.t_end)
        self.pos.append(pos)
        self.att.append(att)
        self.rss.append(world.rss(pos, att, rng))
        self.phase.append(np.asarray(phases, dtype=object)[leg])
        self.t_end += prof.duration_s

    def flight_log(self, spec, adaptive=None):
        """The whole flight as the ``FlightLog`` ``fly-mission`` would have written for ``spec``
        (columns in the field's frame, a simulated source, the trajectory record; ``adaptive``: the
        adaptive settings flown, recorded as ``fly-mission`` records them, which routes
        ``localize`` to the adaptive answer)."""

        origin = spec.field.origin
        pos, att = np.concatenate(self.pos), np.rad2deg(np.concatenate(self.att))
        lat, lon, alt = origin.to_geodetic(pos)
        cols = {
            "t_s": np.concatenate(self.t),
            "lat_deg": lat,
            "lon_deg": lon,
            "alt_m": alt,
            "rel_alt_m": pos[:, 2],
            "roll_deg": att[:, 0],
            "pitch_deg": att[:, 1],
            "yaw_deg": att[:, 2],
            "rss_dbm": np.concatenate(self.rss),
            "phase": np.concatenate(self.phase).astype(str).astype(object),
        }
        traj = spec.trajectory_meta()
        if adaptive is not None:
            traj["adaptive"] = dataclasses.asdict(adaptive)
        src = {"kind": "sim", "model": spec.source.model, "model_params": spec.source.model_params}
        return FlightLog(cols, make_meta(origin, src, trajectory=traj))

    def samples(self, t_max: float = np.inf) -> FlightSamples | None:
        """Mission and adaptive samples up to ``t_max`` (what the live estimate uses)."""
        t, ph = np.concatenate(self.t), np.concatenate(self.phase).astype(str)
        m = np.isin(ph, FLOWN_PHASES) & (t <= t_max)
        if m.sum() < 2:
            return None
        return FlightSamples(
            enu_m=np.concatenate(self.pos)[m],
            rss_dbm=np.concatenate(self.rss)[m],
            attitude_rad=np.concatenate(self.att)[m],
            t_s=t[m],
        )


def estimator(spec):
    """The live estimator with ``localize_log``'s settings for this field
    (``methods.ADAPTIVE_METHOD``)."""
    return make_localizer(
        ADAPTIVE_METHOD, area=spec.field.rover_area, tx_height_m=DEFAULT_TX_HEIGHT_M
    )


@dataclass
class Outcome:
    """A flight's estimates: (x, y, area90, covered) finals and the fast (3 min) one; duration;
    rounds."""

    final: tuple | None
    fast: tuple | None
    duration_s: float
    rounds: int = 0
    notes: list = field(default_factory=list)
    log: SimLog | None = None  # the whole flight (``SimLog.flight_log``: what localize reads)
    # each round's target and the centre it was flown at (moved inside the fence when needed)
    planned: list = field(default_factory=list)


def _estimate(loc, log: SimLog, t_max: float, tx) -> tuple | None:
    f = log.samples(t_max)
    if f is None:
        return None
    try:
        e = loc.predict(f)
    except InputError:
        return None

    reg = e.region(0.9)
    return (
        e.x_m,
        e.y_m,
        None if reg is None else reg.area_m2,
        region_covers(e, tx[0], tx[1], 0.9),
    )


def live_entry(spec, a, log: SimLog, t_max: float) -> dict | None:
    """The live series entry ``fly-mission`` would plan the next round on at ``t_max``
    (``live.summary`` of ``localize``'s answer for the adaptive log so far, flown with settings
    ``a``); None without one."""

    flight = log.flight_log(spec, a)
    keep = np.asarray(flight["t_s"]) <= t_max
    if keep.sum() < 2:
        return None
    try:
        return summary(localize_log(flight.select(keep)), t_max)
    except InputError:
        return None


def _climb(spec, first) -> list:
    home = np.asarray(spec.home_enu, dtype=float)
    return [home, np.array([home[0], home[1], first[2]])]


def fixed_path(spec) -> tuple[np.ndarray, list[str]]:
    """The whole trajectory, then back over home and down: the path (K, 3) and each leg's phase.

    The phases are known here by construction (the simulator builds the legs);
    ``simulate.leg_phases`` derives the same from the geometry of such a path (what ``rfsl
    simulate`` logs)."""
    wps = spec.waypoints_enu()
    home = np.asarray(spec.home_enu, dtype=float)
    path = np.vstack([*_climb(spec, wps[0]), wps, [home[0], home[1], wps[-1, 2]], home])
    return path, [TAKEOFF] + [MISSION] * len(wps) + [RETURN, LAND]


def fixed_flight(
    spec, world: FlightWorld, cfg: SimConfig, rng, loc, fast_s: float = 180.0
) -> Outcome:
    """The whole trajectory, then home."""
    path, names = fixed_path(spec)
    log = SimLog()
    log.fly(path, names, world, cfg, rng)
    return Outcome(
        _estimate(loc, log, np.inf, world.tx),
        _estimate(loc, log, fast_s, world.tx),
        log.t_end,
        log=log,
    )


def adaptive_flight(
    spec, a, world: FlightWorld, cfg: SimConfig, rng, loc, fast_s: float = 180.0
) -> Outcome:
    """The survey, rounds planned from the live series entry (``live_entry``: what ``fly-mission``
    plans on) by ``plan_round``, then home."""

    sv = survey_profile(spec, a.survey_s).vertices
    log = SimLog()
    log.fly(np.vstack([*_climb(spec, sv[0]), sv]), [TAKEOFF] + [MISSION] * len(sv), world, cfg, rng)
    end, rounds, notes, visited, planned = sv[-1], 0, [], [], []
    while True:
        d = live_entry(spec, a, log, log.t_end - a.lead_s)
        if d is None or (d["area_m2"] is not None and d["area_m2"] <= a.target_area_m2):
            notes.append("region small enough" if d is not None else "no estimate")
            break
        target = round_target(spec, a, d, visited, end)
        plan = plan_round(spec, a, target, end, log.t_end)
        notes += plan.notes
        if not plan.ok:
            break
        log.fly(np.vstack([end, plan.waypoints]), [ADAPTIVE] * len(plan.waypoints), world, cfg, rng)
        end, rounds = plan.waypoints[-1], rounds + 1
        visited.append(plan.centre)
        planned.append([[float(v) for v in target], list(plan.centre)])
    back, _, j = ReturnModel.of(spec).legs(end)  # the return the rounds were planned with
    log.fly(back, [RETURN if k < j else LAND for k in range(len(back) - 1)], world, cfg, rng)
    fast = _estimate(loc, log, fast_s, world.tx)
    final = _estimate(loc, log, np.inf, world.tx)
    return Outcome(final, fast, log.t_end, rounds, notes, log, planned)
