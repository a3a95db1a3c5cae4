"""The time budget during a flight: the plan's time per waypoint, the pace measured against it, one warning as
soon as the remaining plan no longer fits, and the overrun recorded in the sidecar.

Why: the pre-flight check (``mission.trajectory.checks``) plans take-off, transit, the trajectory, the return
and the landing with the mission's kinematics; a real autopilot flies its own way (PX4 v1.16 SITL cruised at a
median 5.1 m/s where 5.5 was asked and returned at its own 4.8 m/s: 640-651 s against a 539 s plan and a 600 s
budget, with no warning). During the flight the arm-to-landing time is predicted from the waypoint
times measured so far (vehicle clock, when the mission progress arrived): ``e_k + (D - T_k - D_land) * pace +
D_land``, where ``T_k`` is the plan's time at the last waypoint reached, ``e_k`` the measured one, ``D`` the
plan's total, ``D_land`` its final descent (flown at the autopilot's landing speeds, which a slow cruise does
not change) and ``pace`` the measured over planned time of the mission legs flown so far (1 until
``MIN_PACE_S`` of them); it is never less than the time already used. When it passes the budget the runner
warns once (a line and a ``budget`` event); after landing the sidecar's ``budget`` records planned and used
seconds and the overrun.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

import numpy as np

from mission.trajectory.kinematics import plan_profile

MIN_PACE_S = 30.0  # planned seconds of mission legs before the measured pace is trusted


@dataclass
class BudgetPlan:
    """Planned arm-to-landing time ``duration_s``, the planned time at each waypoint, and the budget."""

    budget_s: float
    t_wp: np.ndarray
    duration_s: float
    land_s: float = 0.0  # the final descent's share of duration_s (vertical: not slowed by a slow cruise)


@dataclass(frozen=True)
class VerticalSpeeds:
    """The autopilot's own climb and descent speeds (m/s): take-off at ``up_mps``; the final descent at
    ``down_mps`` down to ``low_alt_m`` above ground, then at ``land_mps`` (ArduCopter: 0.5 m/s below 10 m,
    which made its landing 36 s where the mission's kinematics plan 12 s)."""

    up_mps: float
    down_mps: float
    land_mps: float
    low_alt_m: float
    hover_s: float = 0.0  # hover over home before the descent of a return (ArduPilot RTL_LOIT_TIME: 5 s)

    def valid(self) -> bool:
        return min(self.up_mps, self.down_mps, self.land_mps) > 0 and self.low_alt_m >= 0 <= self.hover_s


def plan_times(spec, return_speed_mps: float | None = None, vertical: VerticalSpeeds | None = None) -> BudgetPlan:
    """The mission's plan (``spec.flight_path_enu`` with its kinematics, as the pre-flight check), with the
    return leg at ``return_speed_mps`` when the autopilot will not fly it at the mission's speed, and the
    take-off and landing at the autopilot's ``vertical`` speeds when known."""
    path = spec.flight_path_enu()
    kin = spec.kinematics()
    n = len(spec.waypoints_enu())
    drop = path[-2, 2] - path[-1, 2]  # the final descent (both return behaviours end with one)
    if vertical is not None and 0 < vertical.low_alt_m < drop:  # it slows down below low_alt_m: a vertex there
        path = np.vstack([path[:-1], path[-1] + [0.0, 0.0, vertical.low_alt_m], path[-1:]])
    d = np.diff(path, axis=0)
    L = np.linalg.norm(d, axis=1)
    vert = np.abs(d[:, 2]) / np.maximum(L, 1e-9) > 0.7  # plan_profile's rule for take-off and landing legs
    vs = np.full(len(L), kin.climb_rate_mps)
    if vertical is not None:
        vs = np.where(d[:, 2] > 0, vertical.up_mps, vertical.down_mps)
        vs[-1] = vertical.land_mps  # the last leg ends on the ground below low_alt_m
    speeds = np.where(vert, vs, kin.cruise_speed_mps)
    if return_speed_mps and spec.return_behaviour == "rtl":  # legs after the last waypoint (n + 1 on)
        speeds[n + 1:] = np.where(vert[n + 1:], speeds[n + 1:], return_speed_mps)
    keep = L > 1e-6
    prof = plan_profile(path[np.concatenate([[True], keep])], kin, speeds=speeds[keep])
    s_path = np.concatenate([[0.0], np.cumsum(L)])
    t = np.interp(s_path, prof.s_vertex, prof.t_vertex)
    j = len(L) - 1  # the final descent: the last leg, or the last two when it slows down near the ground
    while j > 0 and vert[j - 1] and d[j - 1, 2] < 0:
        j -= 1
    hover = vertical.hover_s if vertical is not None and spec.return_behaviour == "rtl" else 0.0
    return BudgetPlan(float(spec.time_budget_s), t[2:2 + n], prof.duration_s + hover, float(t[-1] - t[j]) + hover)


@dataclass
class BudgetWatch:
    """Measured waypoint times against the plan; ``update`` returns the warning text once, when due."""

    plan: BudgetPlan
    reached_at: list[float] = field(default_factory=list)  # elapsed s when waypoint k was reached
    predicted_s: float | None = None
    warned_at_s: float | None = None
    predicted_at_warning_s: float | None = None

    def pace(self) -> float:
        k = len(self.reached_at) - 1
        if k < 1:
            return 1.0
        planned = self.plan.t_wp[k] - self.plan.t_wp[0]
        flown = self.reached_at[k] - self.reached_at[0]
        return flown / planned if planned >= MIN_PACE_S and flown > 0 else 1.0  # several at once: no pace

    def predict(self, elapsed: float) -> float:
        """Predicted arm-to-landing seconds given what was measured up to ``elapsed``."""
        p, k = self.plan, len(self.reached_at) - 1
        pace, end = self.pace(), p.duration_s - p.land_s  # the landing is added at the plan's own time

        def rest(t_from: float) -> float:
            return (end - t_from) * pace + p.land_s

        if k < 0:
            pred = elapsed + rest(p.t_wp[0]) + max(p.t_wp[0] - elapsed, 0.0)
        else:
            pred = self.reached_at[k] + rest(p.t_wp[k])
            if k + 1 < len(p.t_wp):  # the next waypoint is not reached yet: at least the rest after it
                pred = max(pred, elapsed + rest(p.t_wp[k + 1]))
        return float(max(pred, elapsed))

    def update(self, elapsed: float, reached: int) -> str | None:
        """``reached`` waypoints were reached by ``elapsed`` (s since arming); the warning text once, when
        the predicted landing time first passes the budget."""
        while len(self.reached_at) < min(reached, len(self.plan.t_wp)):
            self.reached_at.append(elapsed)
        self.predicted_s = self.predict(elapsed)
        b = self.plan.budget_s
        if self.warned_at_s is not None or self.predicted_s <= b:
            return None
        self.warned_at_s, self.predicted_at_warning_s = elapsed, self.predicted_s
        if elapsed > b:
            return f"over the time budget: {elapsed:.0f} s flown of {b:.0f} s, still flying"
        return (f"budget will not hold: landing at ~{self.predicted_s:.0f} s of {b:.0f} s "
                f"(pace {self.pace():.2f}, {len(self.reached_at)}/{len(self.plan.t_wp)} wp)")

    def record(self, used_s: float | None) -> dict:
        """The sidecar's ``budget``: planned vs used seconds, overrun flag and amount, when it was warned."""
        b = self.plan.budget_s
        r2 = lambda v: None if v is None or not np.isfinite(v) else round(float(v), 2)  # noqa: E731
        over = used_s is not None and used_s > b
        return {"budget_s": b, "planned_s": r2(self.plan.duration_s), "used_s": r2(used_s), "overrun": bool(over),
                "overrun_s": r2(used_s - b) if over else 0.0, "warned_at_s": r2(self.warned_at_s),
                "predicted_at_warning_s": r2(self.predicted_at_warning_s)}


def used_seconds(events: list[dict], t_start: float | None, t_now: float) -> float | None:
    """Arm-to-disarm seconds on the vehicle's clock from the flight's events (to now if not disarmed)."""
    arm = next((e["t_vehicle_s"] for e in events if e["kind"] == "armed" and e["t_vehicle_s"] is not None), t_start)
    if arm is None:
        return None
    off = [e["t_vehicle_s"] for e in events if e["kind"] == "disarmed" and e["t_vehicle_s"] is not None]
    end = off[-1] if off and off[-1] > arm else t_now
    return float(end - arm) if np.isfinite(end) else None


def _reached(phase: str, item: int, n: int) -> int | None:
    """Waypoints reached when the phase tracker says ``phase``/``item`` (None: no mission progress yet)."""
    if phase == "mission":
        return max(item, 0)
    return n if phase in ("adaptive", "return", "land") else None


async def watch_budget(runner, watch: BudgetWatch) -> None:
    """Task: every 0.25 s compare the flight's progress with the plan; warn once (line + ``budget`` event).
    Waypoint times are the vehicle times at which the progress arrived (``runner.phases``), not the poll's."""
    s, ph, seen, reached = runner.status, runner.phases, 1, 0
    while not runner.landed_disarmed.is_set():
        await asyncio.sleep(0.25)
        if runner.abort.is_set() or getattr(ph, "returning", False):
            return  # a commanded return (Ctrl-C, a failure) ends the plan: nothing left to predict
        if s.t_start is None or not np.isfinite(s.t_start):
            continue
        steps = [(ph.t[i], ph.phase[i], ph.item[i]) for i in range(seen, len(ph.t))]
        seen += len(steps)
        texts = []
        for t, phase, item in steps:
            if (r := _reached(phase, item, s.n_waypoints)) is not None and r > reached:
                reached = r
                texts.append(watch.update(max(t - s.t_start, 0.0), reached))
        texts.append(watch.update(s.elapsed, reached))
        s.predicted_s = watch.predicted_s
        for text in filter(None, texts):
            runner.event("budget", text, warn=True)


def start_budget(runner, return_speed_mps: float | None, vertical: VerticalSpeeds | None) -> BudgetWatch:
    """The watch of ``runner``'s flight, planned with the return, climb and descent speeds the autopilot will
    fly; one line with that plan, a warning before take-off when it no longer fits the budget."""
    spec = runner.spec
    own = return_speed_mps is not None and abs(return_speed_mps - spec.cruise_speed_mps) > 1e-6
    watch = BudgetWatch(plan_times(spec, return_speed_mps if own else None, vertical))
    d, b = watch.plan.duration_s, spec.time_budget_s
    how = [f"return {return_speed_mps:g}"] if own else []
    if vertical is not None:  # one line at 80 columns: "plan 565 s of 600 s (autopilot m/s: up 2.5, ...)"
        v = vertical
        slow = f"/{v.land_mps:g} below {v.low_alt_m:g} m" if v.low_alt_m > 0 and v.land_mps != v.down_mps else ""
        how.append(f"up {v.up_mps:g}, down {v.down_mps:g}{slow}" + (f", hover {v.hover_s:g} s" if v.hover_s else ""))
    text = f"plan {d:.0f} s of {b:g} s" + (f" (autopilot m/s: {'; '.join(how)})" if how else "")
    runner.event("budget", text + (f": {d - b:.0f} s over budget" if d > b else ""), warn=d > b)
    return watch


def close_budget(runner, watch: BudgetWatch) -> dict:
    """The sidecar record, and one line: used vs budget (a warning when over)."""
    now = runner.tel.clock.now() if runner.landed_disarmed.is_set() else float("nan")  # no disarm seen: no
    used = used_seconds(runner.st.events, runner.status.t_start, now)  # extrapolated time (a lost link)
    rec = watch.record(used)
    if used is not None:
        text = f"flight used {used:.0f} s of its {rec['budget_s']:.0f} s budget (plan {rec['planned_s']:.0f} s)"
        if rec["overrun"]:
            text += f": {rec['overrun_s']:.0f} s over"
        runner.event("budget", text, warn=rec["overrun"])
    return rec
