"""The adaptive rounds of a flown mission: an extension of the flight (``AdaptiveRounds``) and the
budget it used.

Why an extension, not a runner: the order of a flight (check, connect, upload, arm, fly, return,
land, close) and its safety paths stay in ``mission.flight.runner``; this adds one coroutine
(``adapt``) run beside the mission, which reads and updates the flight's ``FlightContext``.  Each
round: wait until the current part (the survey, then the last round) has its lead left
(``round_timing``: ``lead_s`` vehicle seconds at every speed-up), take the live estimate of the
rows logged so far, stop if its 90 % region is below target, else plan the next square
(``planner.plan_round``: fence, altitude limits, budget with return and reserve; clipped, shrunk or
refused, each logged as an event) and re-upload the mission extended by it, the final RTL moved
behind it.  The part's last waypoint holds the vehicle (a hold time) while a late plan is made; the
upload ends the wait.  Items already flown keep their indices, so the current item stays valid
(``set_current_mission_item`` re-asserts it: PX4 and the built-in vehicle reset it on upload); a
round that comes too late means the vehicle is already returning, which is safe.  MAVSDK v4 API:
``MissionRawAsync.upload_mission`` and ``set_current_mission_item`` (PX4 and ArduPilot alike, no
guided mode needed).
"""

from __future__ import annotations

import asyncio
import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from mission.adaptive.feasibility import adaptive_violations
from mission.adaptive.planner import (
    mass_near,
    plan_round,
    rival_of,
    round_target,
    smallest_round_s,
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

# A round is planned when its part (the survey, then the last round) has ``lead_s`` vehicle
# seconds left, at every speed-up, from an estimate started then: its data is at most ``lead_s``
# old when the round starts.  Where the estimate, the planning and the upload take longer than that
# (a sped-up vehicle, a loaded machine), the vehicle waits at the part's last waypoint (a hold time
# on it, param1) and the upload ends the wait; only what the budget cannot spare for that wait
# makes the lead longer (``round_timing``).  Before stop 46 the lead itself grew with the speed-up
# (8 wall s: 150 vehicle s at 20x, rounds planned before the survey's last 150 s were flown).
MAX_LEAD_SURVEY_SHARE = 0.5  # a lead never longer than half the survey (a short test survey)
# wall seconds one estimate is taken to last before one is measured (measured: 0.25-1.4 s on a
# quiet 2-core machine, the rounds' answer the slower; 1-7 s beside PX4 SITL; 2-12 s at load 10)
LATENCY_PRIOR_WALL_S = 2.0
# estimates a plan may wait for: the one in progress when the part's lead begins, its own, and one
# more for the spread of their times (PX4 SITL at 10x: a median of 1 s, the longest 5.6 s)
WAIT_ESTIMATES = 3.0
HELD_M = 5.0  # within this of a part's last waypoint, at its index: the vehicle is waiting there


@dataclass(frozen=True)
class RoundTiming:
    """When the next round is planned (``lead_s`` vehicle seconds before its part ends) and how
    long the vehicle may wait at the part's end for it (``hold_s``)."""

    lead_s: float
    hold_s: float


def round_timing(
    latency_wall_s: float | None,
    upload_wall_s: float,
    speedup: float,
    lead_s: float,
    spare_s: float,
    max_lead_s: float,
) -> RoundTiming:
    """The next round's timing: a plan takes ``WAIT_ESTIMATES`` estimates of ``latency_wall_s``
    (None: the prior) and an upload of ``upload_wall_s``, at ``speedup``; the part's ``lead_s``
    covers that first, the wait at its end the rest, at most ``spare_s`` (the budget left after
    the part, its return, the reserve and the smallest round: ``hold_spare``; a round after a
    longer wait could not fit anyway), and only what the wait cannot cover lengthens the lead, to
    at most ``max_lead_s``."""
    lat = LATENCY_PRIOR_WALL_S if latency_wall_s is None else float(latency_wall_s)
    need = (WAIT_ESTIMATES * lat + upload_wall_s) * speedup
    hold = float(np.clip(need - lead_s, 0.0, max(spare_s, 0.0)))
    lead = float(min(max(lead_s, need - hold), max(max_lead_s, lead_s)))
    return RoundTiming(lead, hold)


def hold_spare(spec, a, end, left_s: float, pace=None) -> float:
    """Seconds a wait at ``end`` (a part's last waypoint) may take: ``left_s`` (the budget after
    the part and its return) less the reserve and the smallest round from there
    (``planner.smallest_round_s``), the least any next round needs."""
    return left_s - a.reserve_s - smallest_round_s(spec, a, end, pace)


@dataclass
class AdaptiveRounds:
    """The adaptive finish of ``full_spec`` (``config``: its ``AdaptiveSpec``): the survey part is
    flown first, then rounds planned from the live estimate; the flight's ``extension``
    (``mission.flight.context``)."""

    full_spec: object
    config: object
    rounds: list[dict] = field(default_factory=list)
    flown_s: float | None = None  # the rounds' flown seconds, once ``record`` measured them
    timing: RoundTiming | None = None  # round 1's lead and the survey's wait (``hold_s``)
    # wall seconds a round's upload may take: the longest measured, at least this prior (ArduCopter
    # SITL at 20x: 1 wall s, 20 vehicle s, which a round planned while waiting must allow for)
    upload_wall_s: float = 1.5

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

    def hold_s(self, ctx: FlightContext) -> float:
        """The survey's wait at its last waypoint for round 1 (``round_timing`` with the prior
        latency), within what the budget leaves after the survey's plan; round 1's lead with it."""
        left = self.full_spec.time_budget_s
        planned = getattr(ctx.budget, "planned_s", None)
        if callable(planned):
            left -= planned()
        end = np.asarray(self.spec.waypoints_enu(), dtype=float)[-1]
        spare = hold_spare(self.full_spec, self.config, end, left)
        self.timing = round_timing(
            None, self.upload_wall_s, ctx.speedup, lead_for(self.config), spare, self._max_lead()
        )
        return self.survey_hold_s

    @property
    def survey_hold_s(self) -> float:
        """The survey's wait at its last waypoint (0 before ``hold_s`` sized it)."""
        return 0.0 if self.timing is None else self.timing.hold_s

    def _max_lead(self) -> float:
        return MAX_LEAD_SURVEY_SHARE * float(self.config.survey_s)

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
        return Shown.of_entry(final, ctx.truth, ADAPTIVE_METHOD, ctx.spec.field.origin).lines()


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
    a, timing = _round_config(ctx, ext, returns)
    final = final_phase(spec.return_behaviour)
    hold, k, max_lead = timing.hold_s, 0, ext._max_lead()
    while True:
        lead = await _until_planning_time(ctx, ext, wps, off, hold, max_lead)
        if lead is None:
            return
        # the estimate started now (after one in progress): data at most the lead old
        d = await _estimate_saying_the_wait(ctx, wps, off, hold, k)
        if d is not None:  # the round's estimate is an entry of the series like any other
            estimates.record(ctx, d)
        if d is None:
            ctx.event("adaptive", "no live estimate yet (too few cells): no adaptive round")
            return await _end_hold(ctx, mission_raw, wps, off, hold)
        area = d.get("live_area_m2", d["area_m2"])  # the live method's region (live.summary)
        if area is not None and area <= a.target_area_m2:
            ctx.event(
                "adaptive",
                f"90 % region {area:.0f} m^2 <= {a.target_area_m2:g} m^2: finishing",
            )
            return await _end_hold(ctx, mission_raw, wps, off, hold)
        pace = measured_pace(ctx)
        # the round cannot start before its upload ends (the vehicle may be waiting already)
        rem = max(remaining_s(ctx, wps, off, pace) or 0.0, ext.upload_wall_s * ctx.speedup)
        t_end = ctx.tel.clock.now() - ctx.status.t_start + rem
        visited = [rd["centre"] for rd in ext.rounds]
        target = round_target(spec, a, d, visited, wps[-1])
        plan = plan_round(spec, a, target, wps[-1], t_end, pace, returns)
        for n in plan.notes if plan.ok else ():
            ctx.event("adaptive", f"round {k + 1}: {n}")
        if not plan.ok:
            ctx.event("adaptive", f"round {k + 1} refused: {plan.reason}")
            return await _end_hold(ctx, mission_raw, wps, off, hold)
        left = spec.time_budget_s - t_end - plan.fly_s - plan.return_s
        spare = hold_spare(spec, a, plan.waypoints[-1], left, pace)
        nxt = round_timing(
            ctx.live.latency_s(), ext.upload_wall_s, ctx.speedup, lead_for(a), spare, plan.fly_s
        )
        new = np.vstack([wps, plan.waypoints])
        items = build_items(
            dataclasses.replace(ctx.spec, trajectory=TrajectorySpec("waypoints", {}, new)),
            (ctx.home.latitude_deg, ctx.home.longitude_deg, ctx.home.absolute_altitude_m),
            ctx.ardupilot,
            nxt.hold_s,
        )
        if ctx.mission_done.is_set() or ctx.abort.is_set():
            ctx.event("adaptive", f"round {k + 1} planned too late: already returning")
            return
        cur = ctx.st.progress[0]
        ctx.phases.configure(off, len(items) - 1, final, first_adaptive=off + n_survey)
        t_up = time.monotonic()
        await upload_with_retries(ctx, mission_raw, items, kind="adaptive")
        upload_s = time.monotonic() - t_up
        ext.upload_wall_s = max(ext.upload_wall_s, upload_s)
        # the old RTL became active during the upload
        if ctx.mission_done.is_set() or ctx.abort.is_set():
            await action.return_to_launch()
            ctx.event("adaptive", f"round {k + 1} uploaded too late: return to launch commanded")
            return
        # waiting at the part's end: on to the round (the uploaded part's end no longer holds)
        held = waiting_at_end(ctx, wps, off)
        await mission_raw.set_current_mission_item(
            off + len(wps) if held else max(cur, ctx.phases.raw_item)
        )
        ctx.status.n_waypoints = len(new)
        # land~ now the round's plan, no longer the survey's
        ctx.status.predicted_s = spec.time_budget_s - left
        ext.rounds.append(_round_record(ctx, k, d, target, plan, wps, n_survey, left, pace))
        ext.rounds[-1].update(
            lead_s=round(lead, 1),
            hold_s=round(nxt.hold_s, 1),
            upload_while_waiting=held,
            upload_wall_s=round(upload_s, 2),
        )
        _announce(ctx, ext.rounds[-1], d, a.radius_m)
        wps, k, hold, max_lead = new, k + 1, nxt.hold_s, plan.fly_s


async def _estimate_saying_the_wait(
    ctx: FlightContext, wps: np.ndarray, off: int, hold: float, k: int
) -> dict | None:
    """The round's live estimate (``estimates.estimate``); one line when the vehicle begins to
    wait for it at its part's end (``hold`` s at most), so a hovering vehicle is explained."""
    task = asyncio.ensure_future(estimates.estimate(ctx))
    try:
        said = hold <= 0
        while not task.done():
            if not said and waiting_at_end(ctx, wps, off):
                part = "the survey" if k == 0 else f"round {k}"
                ctx.event(
                    "adaptive",
                    f"waiting at the end of {part} for round {k + 1} (at most {hold:.0f} s)",
                )
                said = True
            await asyncio.wait({task}, timeout=0.05)
        return task.result()
    finally:
        task.cancel()  # cancelled with the flight: no orphan (a no-op once done)


def waiting_at_end(ctx: FlightContext, wps: np.ndarray, off: int) -> bool:
    """Whether the vehicle is at the last of ``wps`` with it the current item: waiting out its
    hold time for the next round."""
    if ctx.st.progress[0] - off != len(wps) - 1 or not ctx.tel.n_pos:
        return False
    return bool(np.linalg.norm(_position_enu(ctx) - wps[-1]) <= HELD_M)


async def _end_hold(ctx: FlightContext, mission_raw, wps: np.ndarray, off: int, hold: float):
    """No more rounds: where the uploaded part ends with a wait (``hold`` s), the vehicle returns
    on reaching its last waypoint instead of waiting (the item after it is the return)."""
    if hold <= 0:
        return
    while not (ctx.mission_done.is_set() or ctx.abort.is_set() or ctx.link_dead.is_set()):
        if waiting_at_end(ctx, wps, off):
            ctx.event("adaptive", f"no round follows: returning without the {hold:.0f} s wait")
            await mission_raw.set_current_mission_item(off + len(wps))
            return
        await asyncio.sleep(0.05)


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


def lead_for(config) -> float:
    """Vehicle seconds before a part's end at which the next round is planned: the settings'
    ``lead_s`` at every speed-up, at most ``MAX_LEAD_SURVEY_SHARE`` of the survey."""
    return min(float(config.lead_s), MAX_LEAD_SURVEY_SHARE * float(config.survey_s))


def _round_config(ctx: FlightContext, ext: AdaptiveRounds, returns: ReturnModel) -> tuple:
    """The rounds' config and round 1's timing (``AdaptiveRounds.hold_s``, set before the
    upload; ``lead_for`` without a wait when it was not); an event when the survey waits at its
    end for round 1 or the lead is longer than the settings' (a sped-up vehicle), and when an
    autopilot's return (``returns``) is longer than the mission's kinematics (the rounds plan
    with it)."""
    a = ext.config
    frm = np.append(ctx.spec.waypoints_enu()[-1][:2], a.altitude(ext.full_spec))
    extra = returns.seconds(frm) - ReturnModel.of(ctx.spec).seconds(frm)
    if extra > 0.5:
        ctx.event(
            "adaptive",
            f"rounds planned with the autopilot's own return and landing ({extra:.0f} s longer)",
        )
    timing = ext.timing or RoundTiming(lead_for(a), 0.0)
    if timing.hold_s > 0 or timing.lead_s > lead_for(a):
        ctx.event(
            "adaptive",
            f"round 1 planned {timing.lead_s:.0f} s before the survey ends; the survey waits up "
            f"to {timing.hold_s:.0f} s at its end for it (speed-up {ctx.speedup:g})",
        )
    return a, timing


async def _until_planning_time(
    ctx: FlightContext, ext: AdaptiveRounds, wps: np.ndarray, off: int, hold: float, max_lead: float
) -> float | None:
    """Wait until the part has its lead left (``round_timing`` with the estimates' time measured
    so far and the ``hold`` already uploaded at its end: a machine measured slow plans earlier,
    up to ``max_lead``) and return that lead; the periodic series goes on meanwhile.  None when
    the mission ends, aborts or loses its link first."""
    a = ext.config
    while True:
        if ctx.mission_done.is_set() or ctx.abort.is_set() or ctx.link_dead.is_set():
            if not ext.rounds and not ctx.abort.is_set() and not ctx.link_dead.is_set():
                _no_round(ctx)
            return None
        rem = remaining_s(ctx, wps, off, measured_pace(ctx)) if ctx.st.was_in_air else None
        lead = round_timing(
            ctx.live.latency_s(), ext.upload_wall_s, ctx.speedup, lead_for(a), hold, max_lead
        ).lead_s
        if rem is not None and rem <= lead:
            return lead
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
        if s is not None and ctx.rows is not None and ctx.rows.t_ref is not None:
            # how old the round's data was when it began (vehicle s): the lead, and any wait
            rd["data_lead_s"] = round(s - ctx.rows.t_ref - rd["estimate"]["t_s"], 1)
        if s is None or e is None:
            continue
        rd["flown_s"] = round(e - s, 1)  # its wait at the end for the next round included
        _judge(ctx, rd, e, ext.config.radius_m)
        if rd["flown_s"] > 1.2 * rd["planned_s"] + 5.0 + rd.get("hold_s", 0.0):  # its wait too
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
    wall = ctx.live.wall_s if ctx.live is not None else []
    walls = [round(float(np.median(wall)), 2), round(max(wall), 2)] if wall else None
    return {
        "budget_s": ext.full_spec.time_budget_s,
        "lead_s": lead_for(ext.config),
        "survey_hold_s": round(ext.survey_hold_s, 1),
        # wall seconds the live estimates took (median, longest): what the waits are sized by
        "estimate_wall_s": walls,
        "rounds": ext.rounds,
    }
