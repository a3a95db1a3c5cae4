"""The adaptive rounds of a flown mission (the ``LiveRunner``'s ``_adapt`` task) and the budget it used.

Each round: wait until the current segment (the survey, then the last round) has ``lead_s`` vehicle seconds
left, take the live estimate of the rows logged so far, stop if its 90 % region is below target, else plan the
next square (``planner.plan_round``: fence, altitude limits, budget with return and reserve; clipped, shrunk or
refused, each logged as an event) and re-upload the mission extended by it, the final RTL moved behind it.
"""

from __future__ import annotations

import asyncio
import dataclasses

import numpy as np

from mission.flight.phases import final_phase
from mission.flightlog import ADAPTIVE, LAND, RETURN
from mission.trajectory.kinematics import plan_profile

MIN_LEAD_WALL_S = 4.0  # wall seconds an estimate, the planning and the upload may take (sped-up vehicles)


def _position_enu(r) -> np.ndarray:
    """The vehicle's latest position: x, y about the mission origin, z the height above home."""
    pos, _ = r.tel.at(np.array([r.tel.covered_until]))
    lat, lon, _, rel = pos[0]
    e = r.spec.field.origin.to_enu(lat, lon)
    return np.array([e[0], e[1], rel])


def remaining_s(r, wps: np.ndarray, offset: int) -> float | None:
    """Vehicle seconds until the last of ``wps`` is reached (None before the first waypoint is flown to)."""
    idx = r.st.progress[0] - offset
    if idx < 0 or not r.tel.n_pos:
        return None
    if idx >= len(wps):
        return 0.0
    return plan_profile(np.vstack([_position_enu(r)[None, :], wps[idx:]]), r.spec.kinematics()).duration_s


def autopilot_return_extra_s(r, frm) -> float:
    """How much longer the autopilot's return and landing from ``frm`` take than the kinematic plan's.

    The runner's budget plan (``flight.budget``) knows the autopilot's own return speed, descent speeds and
    hover (ArduCopter: RTL_LOIT_TIME 5 s, LAND_SPEED 0.5 m/s below 10 m: its return took 85 s against 55 s
    planned on the SITL, 615 s of 600 flown); its return from the survey's end against ours is the extra."""
    from mission.adaptive.planner import return_s

    plan = getattr(getattr(r, "budget", None), "plan", None)
    try:
        theirs = float(plan.duration_s - plan.t_wp[-1])
    except (AttributeError, IndexError, TypeError):
        return 0.0
    return max(0.0, theirs - return_s(r.spec, frm))


async def _upload(r, mission_raw, items) -> None:
    from mission.flight.plan import upload_items

    await upload_items(mission_raw, items, on_retry=lambda why: r.event(
        "adaptive", f"upload failed ({why}); retrying", warn=True))


async def adapt(r, action, mission_raw) -> None:
    """Plan, check and upload rounds until the region is small, no round fits, or the mission ends; a flight
    that ends before its first round was planned says so (the live estimate was late: a starved worker)."""
    try:
        await _adapt_rounds(r, action, mission_raw)
    except asyncio.CancelledError:
        if not r.rounds and not r.abort.is_set():
            r.event("adaptive", "no adaptive round: the survey ended before one was planned (live estimate "
                                "late)", warn=True)
        raise


async def _adapt_rounds(r, action, mission_raw) -> None:
    from mission.adaptive.planner import choose_target, plan_round
    from mission.spec import TrajectorySpec
    from mission.trajectory.items import build_items

    a, spec = r.adaptive, r.full_spec
    wps = np.asarray(r.spec.waypoints_enu(), dtype=float)
    off, n_survey = r.status.waypoint_offset, len(wps)
    extra = autopilot_return_extra_s(r, wps[-1])
    if extra > 0.5:
        a = dataclasses.replace(a, reserve_s=a.reserve_s + extra)
        r.event("adaptive", f"{extra:.0f} s more reserved: the autopilot's own return and landing")
    final = final_phase(spec.return_behaviour)
    lead = max(a.lead_s, MIN_LEAD_WALL_S * r.speedup)
    if lead > a.lead_s:
        r.event("adaptive", f"rounds planned {lead:.0f} s ahead ({MIN_LEAD_WALL_S:g} s wall-clock at speed-up "
                            f"{r.speedup:g})")
    k = 0
    while True:
        while True:
            if r.mission_done.is_set() or r.abort.is_set() or r.link_dead.is_set():
                return
            rem = remaining_s(r, wps, off) if r.st.was_in_air else None
            r.planning = rem is not None and rem <= 1.5 * lead
            if rem is not None and rem <= lead:
                break
            await asyncio.sleep(0.05)
        try:
            d = await r.estimate()
        finally:
            r.planning = False
        if d is None:
            r.event("adaptive", "no live estimate yet (too few cells): no adaptive round")
            return
        if d["area_m2"] is not None and d["area_m2"] <= a.target_area_m2:
            r.event("adaptive", f"90 % region {d['area_m2']:.0f} m^2 <= {a.target_area_m2:g} m^2: finishing")
            return
        rem = remaining_s(r, wps, off) or 0.0
        t_end = r.tel.clock.now() - r.status.t_start + rem
        visited = [rd["centre"] for rd in r.rounds]
        target = choose_target((d["x_m"], d["y_m"]), d.get("candidates") if a.explore else None, visited, a.radius_m)
        plan = plan_round(spec, a, target, wps[-1], t_end)
        for n in plan.notes if plan.ok else ():
            r.event("adaptive", f"round {k + 1}: {n}")
        if not plan.ok:
            r.event("adaptive", f"round {k + 1} refused: {plan.reason}")
            return
        new = np.vstack([wps, plan.waypoints])
        items = build_items(dataclasses.replace(r.spec, trajectory=TrajectorySpec("waypoints", {}, new)),
                            (r.home.latitude_deg, r.home.longitude_deg, r.home.absolute_altitude_m), off == 3)
        if r.mission_done.is_set() or r.abort.is_set():
            r.event("adaptive", f"round {k + 1} planned too late: already returning")
            return
        cur = r.st.progress[0]
        r.phases.configure(off, len(items) - 1, final, first_adaptive=off + n_survey)
        await _upload(r, mission_raw, items)
        if r.mission_done.is_set() or r.abort.is_set():  # the old RTL became active during the upload
            await action.return_to_launch()
            r.event("adaptive", f"round {k + 1} uploaded too late: return to launch commanded")
            return
        await mission_raw.set_current_mission_item(max(cur, r.phases.raw_item))
        r.status.n_waypoints = len(new)
        left = spec.time_budget_s - t_end - plan.fly_s - plan.return_s
        r.status.predicted_s = spec.time_budget_s - left  # land~ now the round's plan, no longer the survey's
        r.rounds.append({"round": k + 1, "t_plan_s": round(r.tel.clock.now() - r.status.t_start, 1),
                         "estimate": d, "target": target, "centre": plan.centre, "radius_m": plan.radius_m,
                         "first_item": len(wps) - n_survey, "n_waypoints": len(plan.waypoints),
                         "planned_s": round(plan_profile(np.vstack([wps[-1:], plan.waypoints]),
                                                         spec.kinematics()).duration_s, 1),
                         "budget_left_after_return_s": round(left, 1), "notes": plan.notes})
        r.event("adaptive", f"round {k + 1}: {2 * plan.radius_m:.0f} m square at ({plan.centre[0]:.0f}, "
                            f"{plan.centre[1]:.0f}) m, {r.rounds[-1]['planned_s']:.0f} s; {left:.0f} s spare "
                            "after the return")
        wps, k = new, k + 1


def budget_report(r) -> dict:
    """Each round's flown against planned time; warns on overruns (the flight's budget: ``flight.budget``)."""
    ph = np.asarray(r.phases.phase)
    t = np.asarray(r.phases.t)
    item = np.asarray(r.phases.item)
    starts = []
    for rd in r.rounds:
        hit = np.flatnonzero((ph == ADAPTIVE) & (item >= rd["first_item"]))
        starts.append(float(t[hit[0]]) if len(hit) else None)
    after = np.flatnonzero(np.isin(ph, (RETURN, LAND)) & (t > (starts[0] if starts and starts[0] else np.inf)))
    t_ret = float(t[after[0]]) if len(after) else None
    for j, rd in enumerate(r.rounds):
        s = starts[j]
        e = starts[j + 1] if j + 1 < len(starts) else t_ret
        if s is not None and e is None:  # the log ended in the round (link lost): flown until the last telemetry
            e = float(r.tel.covered_until) if np.isfinite(r.tel.covered_until) else None
        if s is None or e is None:
            continue
        rd["flown_s"] = round(e - s, 1)
        if rd["flown_s"] > 1.2 * rd["planned_s"] + 5.0:
            r.event("budget", f"adaptive round {rd['round']} overran: {rd['flown_s']:.0f} s flown against "
                              f"{rd['planned_s']:.0f} s planned", warn=True)
    flown = sum(rd.get("flown_s", 0.0) for rd in r.rounds)
    planned = sum(rd["planned_s"] for rd in r.rounds)
    r.rounds_flown_s = flown  # the budget's closing line says survey and rounds apart (flight.budget)
    r.event("adaptive", f"adaptive: {len(r.rounds)} round(s), {flown:.0f} s flown, {planned:.0f} s planned")
    return {"budget_s": r.full_spec.time_budget_s, "rounds": r.rounds}  # time used: the sidecar's budget
