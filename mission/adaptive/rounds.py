"""The adaptive rounds of a flown mission: an extension of the flight (``AdaptiveRounds``) and the
budget it used.

Why an extension, not a runner: the order of a flight (check, connect, upload, arm, fly, return,
land, close) and its safety paths stay in ``mission.flight.runner``; this adds one coroutine
(``adapt``) run beside the mission, which reads and updates the flight's ``FlightContext``.  Each
round: wait until the current segment (the survey, then the last round) has ``lead_s`` vehicle
seconds left, take the live estimate of the rows logged so far, stop if its 90 % region is below
target, else plan the next square (``planner.plan_round``: fence, altitude limits, budget with
return and reserve; clipped, shrunk or refused, each logged as an event) and re-upload the mission
extended by it, the final RTL moved behind it.  Items already flown keep their indices, so the
current item stays valid (``set_current_mission_item`` re-asserts it: PX4 and the built-in vehicle
reset it on upload); a round that comes too late means the vehicle is already returning, which is
safe.  MAVSDK v4 API: ``MissionRawAsync.upload_mission`` and ``set_current_mission_item`` (PX4 and
ArduPilot alike, no guided mode needed).
"""

from __future__ import annotations

import asyncio
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mission.adaptive.feasibility import adaptive_violations
from mission.adaptive.planner import (
    mass_near,
    plan_round,
    rival_of,
    round_target,
    survey_spec,
    verdict,
)
from mission.flight import estimates
from mission.flight.context import FlightContext, FlightError
from mission.flight.phases import final_phase
from mission.flight.plan import upload_with_retries
from mission.flightlog import ADAPTIVE, LAND, RETURN
from mission.localize.methods import ADAPTIVE_METHOD
from mission.localize.render import Shown
from mission.spec import TrajectorySpec
from mission.trajectory.autopilot import ReturnModel
from mission.trajectory.items import build_items
from mission.trajectory.kinematics import plan_profile

# wall seconds an estimate, the planning and the upload may take (sped-up vehicles); 4 s was too
# little for PX4 SITL at 10x on a loaded 2-core machine: the estimate came back after the survey
# ended and no round was flown
MIN_LEAD_WALL_S = 8.0
# but never more than this share of the survey (vehicle seconds): at 15x, 8 wall s were 120
# vehicle s, more than a 100 s survey, and the round was planned before the survey had an estimate
MAX_LEAD_SURVEY_SHARE = 0.5


@dataclass
class AdaptiveRounds:
    """The adaptive finish of ``full_spec`` (``config``: its ``AdaptiveSpec``): the survey part is
    flown first, then rounds planned from the live estimate; the flight's ``extension``
    (``mission.flight.context``)."""

    full_spec: object
    config: object
    rounds: list[dict] = field(default_factory=list)
    flown_s: float | None = None  # the rounds' flown seconds, once ``record`` measured them

    def __post_init__(self) -> None:
        self.spec = survey_spec(self.full_spec, self.config.survey_s)
        self.update_s = self.config.update_s

    def trajectory_meta(self) -> dict:
        meta = self.full_spec.trajectory_meta()
        meta["adaptive"] = dataclasses.asdict(self.config)
        return meta

    def check(self, ctx: FlightContext) -> None:
        """The adaptive settings again with the autopilot's own return (known now, ``ctx.budget``):
        refused before the upload and take-off, exit 2, when they leave no round."""
        if v := adaptive_violations(self.full_spec, self.config, autopilot_returns(ctx)):
            raise FlightError(f"{self.full_spec.source_name}, field '{v[0][0]}': {v[0][1]}", 2)

    async def fly(self, ctx: FlightContext, action, mission_raw) -> None:
        try:
            await adapt(ctx, self, action, mission_raw)
        except asyncio.CancelledError:  # the mission ended first: said when it left no round at all
            if not self.rounds and not ctx.abort.is_set():
                _no_round(ctx)
            raise
        except Exception as e:  # the survey's RTL stays uploaded: the vehicle returns by itself
            ctx.event(
                "adaptive", f"adaptive part stopped ({type(e).__name__}: {e}); returning", warn=True
            )

    def record(self, ctx: FlightContext) -> tuple[str, dict]:
        return "adaptive", budget_report(ctx, self)

    def result_lines(self, ctx: FlightContext) -> list[str]:
        final = ctx.live.final
        if not final:
            return ["no final estimate (too few samples)"]
        return Shown.of_entry(final, ctx.truth, ADAPTIVE_METHOD).lines()


def _no_round(ctx: FlightContext) -> None:
    """One line when the survey ended before a round was planned (the live estimate was late: a
    starved worker)."""
    ctx.event(
        "adaptive",
        "no adaptive round: the survey ended before one was planned (live estimate late)",
        warn=True,
    )


def _position_enu(ctx: FlightContext) -> np.ndarray:
    """The vehicle's latest position: x, y about the mission origin, z the height above home."""
    pos, _ = ctx.tel.at(np.array([ctx.tel.covered_until]))
    lat, lon, _, rel = pos[0]
    e = ctx.spec.field.origin.to_enu(lat, lon)
    return np.array([e[0], e[1], rel])


def remaining_s(ctx: FlightContext, wps: np.ndarray, offset: int, pace=None) -> float | None:
    """Vehicle seconds until the last of ``wps`` is reached (None before the first waypoint is flown
    to), at the measured ``pace`` (``flight.budget.Pace``) when given."""
    idx = ctx.st.progress[0] - offset
    if idx < 0 or not ctx.tel.n_pos:
        return None
    if idx >= len(wps):
        return 0.0
    t = plan_profile(
        np.vstack([_position_enu(ctx)[None, :], wps[idx:]]), ctx.spec.kinematics()
    ).duration_s
    return t if pace is None else pace.flown(t, len(wps) - idx)


def measured_pace(ctx: FlightContext):
    """The pace the flight's budget watch measured on the survey, each term at least the
    autopilot's known one (``Pace.at_least``: a round's legs are short, where a cost per leg the
    survey's long legs could not show counts most); None without a watch."""
    watch = getattr(ctx, "budget", None)
    if not hasattr(watch, "pace_model"):
        return None
    return watch.pace_model().at_least(getattr(watch, "prior", None))


def autopilot_returns(ctx: FlightContext) -> ReturnModel:
    """The autopilot's own return and landing from anywhere, as the runner's budget plan knows
    them once connected (``flight.budget.plan_times``: its return speed, its return altitude,
    its climb and landing speeds, hover and disarm delay); the mission's kinematics before that.

    Why: ArduCopter SITL's return took 85 s against 55 s planned (615 s of 600 flown); PX4 SITL
    climbed from a 15 m round to its 30 m return altitude and landed at its own speeds, 108 s where
    the rounds had planned about 60 (613 s of 600)."""
    plan = getattr(getattr(ctx, "budget", None), "plan", None)
    returns = getattr(plan, "returns", None)
    return returns if isinstance(returns, ReturnModel) else ReturnModel.of(ctx.spec)


async def adapt(ctx: FlightContext, ext: AdaptiveRounds, action, mission_raw) -> None:
    """Plan, check and upload rounds until the region is small, no round fits, or the mission
    ends."""
    spec = ext.full_spec
    wps = np.asarray(ctx.spec.waypoints_enu(), dtype=float)
    off, n_survey = ctx.status.waypoint_offset, len(wps)
    returns = autopilot_returns(ctx)
    a, lead = _round_config(ctx, ext, returns)
    final = final_phase(spec.return_behaviour)
    k = 0
    while True:
        if not await _until_planning_time(ctx, ext, wps, off, lead):
            return
        try:
            d = await estimates.estimate(ctx)
        finally:
            ctx.live.planning = False
        if d is not None:  # the round's estimate is an entry of the series like any other
            estimates.record(ctx, d)
        if d is None:
            ctx.event("adaptive", "no live estimate yet (too few cells): no adaptive round")
            return
        if d["area_m2"] is not None and d["area_m2"] <= a.target_area_m2:
            ctx.event(
                "adaptive",
                f"90 % region {d['area_m2']:.0f} m^2 <= {a.target_area_m2:g} m^2: finishing",
            )
            return
        pace = measured_pace(ctx)
        rem = remaining_s(ctx, wps, off, pace) or 0.0
        t_end = ctx.tel.clock.now() - ctx.status.t_start + rem
        visited = [rd["centre"] for rd in ext.rounds]
        target = round_target(spec, a, d, visited, wps[-1])
        plan = plan_round(spec, a, target, wps[-1], t_end, pace, returns)
        for n in plan.notes if plan.ok else ():
            ctx.event("adaptive", f"round {k + 1}: {n}")
        if not plan.ok:
            ctx.event("adaptive", f"round {k + 1} refused: {plan.reason}")
            return
        new = np.vstack([wps, plan.waypoints])
        items = build_items(
            dataclasses.replace(ctx.spec, trajectory=TrajectorySpec("waypoints", {}, new)),
            (ctx.home.latitude_deg, ctx.home.longitude_deg, ctx.home.absolute_altitude_m),
            ctx.ardupilot,
        )
        if ctx.mission_done.is_set() or ctx.abort.is_set():
            ctx.event("adaptive", f"round {k + 1} planned too late: already returning")
            return
        cur = ctx.st.progress[0]
        ctx.phases.configure(off, len(items) - 1, final, first_adaptive=off + n_survey)
        await upload_with_retries(ctx, mission_raw, items, kind="adaptive")
        # the old RTL became active during the upload
        if ctx.mission_done.is_set() or ctx.abort.is_set():
            await action.return_to_launch()
            ctx.event("adaptive", f"round {k + 1} uploaded too late: return to launch commanded")
            return
        await mission_raw.set_current_mission_item(max(cur, ctx.phases.raw_item))
        ctx.status.n_waypoints = len(new)
        left = spec.time_budget_s - t_end - plan.fly_s - plan.return_s
        # land~ now the round's plan, no longer the survey's
        ctx.status.predicted_s = spec.time_budget_s - left
        ext.rounds.append(_round_record(ctx, k, d, target, plan, wps, n_survey, left, pace))
        _announce(ctx, ext.rounds[-1], d, a.radius_m)
        wps, k = new, k + 1


def _announce(ctx: FlightContext, rd: dict, d: dict, visit_m: float) -> None:
    """Round ``rd``'s line, with the two hypotheses it is flown to tell apart (its target and the
    live estimate ``d``'s most probable rival, ``planner.rival_of``), kept in its record."""
    target, plan_c = rd["target"], rd["centre"]
    rd["hypotheses"] = hyp = {
        "target": [*target, mass_near(target, d.get("candidates"), visit_m)],
        "rival": rival_of(target, (d["x_m"], d["y_m"]), d.get("candidates"), visit_m),
    }
    rival = hyp["rival"]
    tells = (
        f", to tell ({target[0]:.0f}, {target[1]:.0f}) m from ({rival[0]:.0f}, {rival[1]:.0f}) m"
        if rival is not None
        else ""
    )
    ctx.event(
        "adaptive",
        f"round {rd['round']}: {2 * rd['radius_m']:.0f} m square at ({plan_c[0]:.0f}, "
        f"{plan_c[1]:.0f}) m{tells}, {rd['planned_s']:.0f} s; "
        f"{rd['budget_left_after_return_s']:.0f} s spare after the return",
    )


def _round_config(ctx: FlightContext, ext: AdaptiveRounds, returns: ReturnModel) -> tuple:
    """The rounds' config and how far ahead a round is planned (at least ``MIN_LEAD_WALL_S`` of
    wall-clock time, at most ``MAX_LEAD_SURVEY_SHARE`` of the survey); a change is an event, as is
    an autopilot's return (``returns``) longer than the mission's kinematics (the rounds plan with
    it)."""
    a = ext.config
    frm = np.append(ctx.spec.waypoints_enu()[-1][:2], a.altitude(ext.full_spec))
    extra = returns.seconds(frm) - ReturnModel.of(ctx.spec).seconds(frm)
    if extra > 0.5:
        ctx.event(
            "adaptive",
            f"rounds planned with the autopilot's own return and landing ({extra:.0f} s longer)",
        )
    lead = min(max(a.lead_s, MIN_LEAD_WALL_S * ctx.speedup), MAX_LEAD_SURVEY_SHARE * a.survey_s)
    if lead > a.lead_s:
        ctx.event(
            "adaptive",
            f"rounds planned {lead:.0f} s ahead ({lead / ctx.speedup:.1f} s wall-clock at "
            f"speed-up {ctx.speedup:g}; at most half the survey)",
        )
    return a, lead


async def _until_planning_time(
    ctx: FlightContext, ext: AdaptiveRounds, wps: np.ndarray, off: int, lead: float
) -> bool:
    """Wait until the mission has ``lead`` s left (from 1.1 ``lead`` the periodic series starts no
    new estimate, so the worker is free; before, the series keeps its period); False when the
    mission ends, aborts or loses its link first."""
    while True:
        if ctx.mission_done.is_set() or ctx.abort.is_set() or ctx.link_dead.is_set():
            if not ext.rounds and not ctx.abort.is_set() and not ctx.link_dead.is_set():
                _no_round(ctx)
            return False
        rem = remaining_s(ctx, wps, off, measured_pace(ctx)) if ctx.st.was_in_air else None
        ctx.live.planning = rem is not None and rem <= 1.1 * lead
        if rem is not None and rem <= lead:
            return True
        await asyncio.sleep(0.05)


def _round_record(ctx: FlightContext, k: int, d, target, plan, wps, n_survey, left, pace) -> dict:
    """Round ``k + 1``'s entry in the sidecar: when and from which estimate it was planned, its
    square, waypoints, planned time (at the measured ``pace``) and the budget left after the
    return."""
    return {
        "round": k + 1,
        "t_plan_s": round(ctx.tel.clock.now() - ctx.status.t_start, 1),
        "estimate": d,
        "target": target,
        "centre": plan.centre,
        "radius_m": plan.radius_m,
        "first_item": len(wps) - n_survey,
        "n_waypoints": len(plan.waypoints),
        "planned_s": round(plan.fly_s, 1),  # at the measured pace
        "pace": None if pace is None else [round(pace.scale, 3), round(pace.per_leg_s, 2)],
        "budget_left_after_return_s": round(left, 1),
        "notes": plan.notes,
    }


def _judge(ctx: FlightContext, rd: dict, t_end: float, visit_m: float) -> None:
    """Which of round ``rd``'s hypotheses the first estimate taken after it (vehicle time
    ``t_end``) ruled out (``planner.verdict``): in its sidecar record and one event line."""
    hyp = rd.get("hypotheses")
    if not hyp or hyp.get("rival") is None or ctx.rows.t_ref is None:
        return
    t_log = t_end - ctx.rows.t_ref - 0.5
    after = next((d for d in ctx.live.estimates if d["t_s"] >= t_log and "candidates" in d), None)
    if after is None:
        return
    gone = verdict(hyp, after["candidates"], visit_m)
    rd["ruled_out"], rd["judged_at_t_s"] = gone, after["t_s"]
    said = (
        "ruled out neither hypothesis"
        if gone is None
        else f"ruled out ({hyp[gone][0]:.0f}, {hyp[gone][1]:.0f}) m, its {gone}"
    )
    ctx.event("adaptive", f"round {rd['round']} {said} (estimate at t={after['t_s']:.0f} s)")


def budget_report(ctx: FlightContext, ext: AdaptiveRounds) -> dict:
    """Each round's flown against planned time; warns on overruns (the flight's budget:
    ``flight.budget``)."""
    ph = np.asarray(ctx.phases.phase)
    t = np.asarray(ctx.phases.t)
    item = np.asarray(ctx.phases.item)
    starts = []
    for rd in ext.rounds:
        hit = np.flatnonzero((ph == ADAPTIVE) & (item >= rd["first_item"]))
        starts.append(float(t[hit[0]]) if len(hit) else None)
    after = np.flatnonzero(
        np.isin(ph, (RETURN, LAND)) & (t > (starts[0] if starts and starts[0] else np.inf))
    )
    t_ret = float(t[after[0]]) if len(after) else None
    for j, rd in enumerate(ext.rounds):
        s = starts[j]
        e = starts[j + 1] if j + 1 < len(starts) else t_ret
        # the log ended in the round (link lost): flown until the last telemetry
        if s is not None and e is None:
            e = float(ctx.tel.covered_until) if np.isfinite(ctx.tel.covered_until) else None
        if s is None or e is None:
            continue
        rd["flown_s"] = round(e - s, 1)
        _judge(ctx, rd, e, ext.config.radius_m)
        if rd["flown_s"] > 1.2 * rd["planned_s"] + 5.0:
            ctx.event(
                "budget",
                f"adaptive round {rd['round']} overran: {rd['flown_s']:.0f} s flown against "
                f"{rd['planned_s']:.0f} s planned",
                warn=True,
            )
    flown = sum(rd.get("flown_s", 0.0) for rd in ext.rounds)
    planned = sum(rd["planned_s"] for rd in ext.rounds)
    ext.flown_s = flown  # the budget's closing line says survey and rounds apart (flight.budget)
    ctx.event(
        "adaptive",
        f"adaptive: {len(ext.rounds)} round(s), {flown:.0f} s flown, {planned:.0f} s planned",
    )
    # time used: the sidecar's budget
    return {
        "budget_s": ext.full_spec.time_budget_s,
        "rounds": ext.rounds,
    }
