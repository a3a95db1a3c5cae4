"""The time budget during a flight: the plan's time per waypoint, the pace measured against it, one
warning as soon as the remaining plan no longer fits, and the overrun recorded in the sidecar.

Why: the pre-flight check (``mission.trajectory.checks``) plans take-off, transit, the trajectory,
the return and the landing with the mission's kinematics; a real autopilot flies its own way (PX4
v1.16 SITL cruised at a median 5.1 m/s where 5.5 was asked and returned at its own 4.8 m/s: 640-651
s against a 539 s plan and a 600 s budget, with no warning). During the flight the arm-to-landing
time is predicted from the waypoint times measured so far (vehicle clock, when the mission progress
arrived): ``e_k + (D - T_k - D_land) * pace + D_land``, where ``T_k`` is the plan's time at the last
waypoint reached, ``e_k`` the measured one, ``D`` the plan's total, ``D_land`` its final descent
(flown at the autopilot's landing speeds, which a slow cruise does not change) and ``pace`` the
measured over planned time of the mission legs flown so far (1 until ``MIN_PACE_S`` of them); it is
never less than the time already used. When it passes the budget the runner warns once (a line and a
``budget`` event); after landing the sidecar's ``budget`` records planned and used seconds and the
overrun.

A budget that holds: the pace is fitted per leg once ``MIN_FIT_LEGS`` legs are measured (``Pace``:
flown = planned x (scale + headwind . leg direction) + a fixed cost per leg; PX4 v1.16 SITL slows to
a stop at every waypoint, 3 s a leg, so it fell further behind as the spiral's legs shortened; in
wind the upwind legs are the slow ones), under a robust loss (one slow leg is not a pace), the
return is predicted from wherever the mission would end (``BudgetPlan.ret_s``), and touchdown to
disarm is the autopilot's known delay (``LANDED_TO_DISARM_S``). When the prediction passes the
budget less its reserve the mission's ``budget_policy`` acts (``decide``): ``trim`` (default) drops
the tail waypoints that no longer fit, as late as is safe (``TRIM_LOOKAHEAD`` waypoints before the
cut, when the pace is best known), ``return`` returns to launch at once, ``warn`` only warns. The
sidecar's ``budget`` records the policy, what was dropped and the measured arm-to-disarm time.
"""

from __future__ import annotations

import asyncio
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mission.flight.plan import upload_with_retries
from mission.flightlog import LAND, RETURN
from mission.robust import huber_lstsq
from mission.spec import TrajectorySpec
from mission.trajectory.autopilot import Pace, ReturnModel, VerticalSpeeds, leg_speeds
from mission.trajectory.items import build_items
from mission.trajectory.kinematics import plan_profile

MIN_PACE_S = 30.0  # planned seconds of mission legs before the measured pace is trusted
# measured legs before the per-leg cost and the headwind are fitted (fewer: the prior or the ratio
# alone).  Why eight: two legs in each of the spiral's four directions for four terms; fewer cannot
# tell one slow leg (a gust) from a cost per leg or a wind.  On the spiral's plan one leg 1-5 s slow
# over-predicted the legs to come by up to 77 s with a robust fit from four legs (least squares:
# 49 s); replayed on stored SITL spirals, from eight with the headwind the worst over-prediction
# was 1.2 s in an 8 m/s wind and -1.7 s after a 2.55 s slow leg (benchmarks/replay_pace.py)
MIN_FIT_LEGS = 8
# the scale of the pace fit's Huber loss (s): about the legs' timing noise, so that the fit is
# nearly a least-absolute-deviations one and one slow leg counts linearly, not squared.  Measured
# about each flight's own fit: ArduCopter 4.7 SITL |residual| median 0.05 s, 90 % 0.16 s (38
# spirals), PX4 v1.16 SITL 0.34 / 1.09 s (35; benchmarks/replay_pace.py)
PACE_FIT_SCALE_S = 0.1
# waypoints before the cut at which the tail is dropped: the upload takes a few wall seconds, tens
# of vehicle seconds at a speed-up, and may be retried (PX4 SITL at 10x on a loaded machine: one
# TIMEOUT, the cut came a leg late and the spiral landed at 647 s of 600 with 3)
TRIM_LOOKAHEAD = 5
# touchdown to disarm (s, vehicle clock): not in the kinematic plan.  Measured: PX4 v1.16 SITL 7.2 s
# (land detector + COM_DISARM_LAND 2 s), ArduCopter 4.7 SITL 3 s; the built-in vehicle disarms at
# touchdown.
LANDED_TO_DISARM_S = {"PX4": 7.2, "ARDUPILOT": 3.0}
# a waypoint is timed where the track passed closest to it when that was within this distance (m);
# measured: ArduCopter 4.7 and PX4 v1.16 SITL passed within 1.8 and 2.0 m of every spiral waypoint
# (996 arrivals)
ARRIVAL_RADIUS_M = 10.0


# The known pace of an autopilot's mission legs (``Pace``), used before ``MIN_FIT_LEGS`` legs are
# measured: the pre-flight plan and the first trims.  Measured: PX4 v1.16 SITL (SIH, MPC_XY_CRUISE
# 5.5) flew the spiral's legs at 1.03 x planned + 3 s a leg (it slows to a stop at every waypoint;
# 634-641 s arm to disarm against a 566 s kinematic plan).  ArduCopter: none (its arm to disarm is
# within 5 % of the plan with its own speeds: tests/test_ardupilot_e2e.py).
PACE_PRIOR = {"PX4": Pace(1.03, 3.0)}


def fit_pace(
    planned: np.ndarray, n_legs: np.ndarray, flown: np.ndarray, dirs: np.ndarray | None = None
) -> Pace:
    """``Pace`` from measured segments (each ``n_legs`` legs planned at ``planned`` s in total,
    flown in ``flown`` s; ``dirs``: each segment's planned seconds times its legs' unit directions,
    summed, n x 2, for the headwind), robust to one slow leg (Huber loss at ``PACE_FIT_SCALE_S``: a
    gust's 2.55 s on one leg is not a cost on every leg to come, while a wind slows every upwind
    leg and is fitted as such); no cost per leg when it would come out negative, no headwind when
    it would reverse a leg (|headwind| >= scale / 2), the plain ratio when the fit is degenerate
    (legs of one length) or the scale is outside 0.5..3."""
    planned, n_legs, flown = (np.asarray(a, dtype=float) for a in (planned, n_legs, flown))
    ratio = Pace(float(np.clip(flown.sum() / max(planned.sum(), 1e-9), 0.5, 3.0)), 0.0)
    cols = [planned, n_legs] + ([] if dirs is None else list(np.asarray(dirs, dtype=float).T))
    A = np.column_stack(cols)
    if len(flown) < A.shape[1] or np.linalg.matrix_rank(A) < A.shape[1]:
        return ratio if dirs is None else fit_pace(planned, n_legs, flown)
    x = huber_lstsq(A, flown, PACE_FIT_SCALE_S)
    if x[1] < 0:  # faster than planned, or a slow long leg: no cost per leg, as robustly
        x = np.insert(huber_lstsq(np.delete(A, 1, axis=1), flown, PACE_FIT_SCALE_S), 1, 0.0)
    a, b, wind = float(x[0]), float(x[1]), x[2:]
    if len(wind) and np.hypot(*wind) >= a / 2:
        return fit_pace(planned, n_legs, flown)
    if not 0.5 <= a <= 3.0:
        return ratio
    return Pace(a, b, (float(wind[0]), float(wind[1])) if len(wind) else (0.0, 0.0))


@dataclass
class BudgetPlan:
    """Planned arm-to-landing time ``duration_s``, the planned time at each waypoint, and the
    budget."""

    budget_s: float
    t_wp: np.ndarray
    duration_s: float
    land_s: float = (
        0.0  # the final descent's share of duration_s (vertical: not slowed by a slow cruise)
    )
    ret_s: np.ndarray | None = (
        None  # seconds from waypoint j back over home (the return if the mission ends at j)
    )
    disarm_s: float = 0.0  # touchdown to disarm (the autopilot's), inside duration_s and land_s
    returns: ReturnModel | None = None  # the return from anywhere (an adaptive round's end)
    # unit direction (east, north) of the leg into each waypoint (row 0: the transit, zero) and of
    # the return from each waypoint (zero where not straight home): the headwind's legs
    u_wp: np.ndarray | None = None
    u_ret: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.ret_s is None:  # only the full mission's return is known
            self.ret_s = np.full(len(self.t_wp), self.duration_s - self.land_s - self.t_wp[-1])
        if self.u_wp is None:
            self.u_wp = np.zeros((len(self.t_wp), 2))
        if self.u_ret is None:
            self.u_ret = np.zeros((len(self.t_wp), 2))

    def end_s(self, last: int) -> float:
        """Planned arm-to-disarm seconds when the mission ends at waypoint ``last`` (its tail
        dropped)."""
        return float(self.t_wp[last] + self.ret_s[last] + self.land_s)


def plan_times(
    spec,
    return_speed_mps: float | None = None,
    vertical: VerticalSpeeds | None = None,
    disarm_s: float = 0.0,
) -> BudgetPlan:
    """The mission's plan (``spec.flight_path_enu`` with its kinematics, as the pre-flight check),
    with the return leg at ``return_speed_mps`` when the autopilot will not fly it at the mission's
    speed, the take-off, return altitude and landing at the autopilot's ``vertical`` settings when
    known, and ``disarm_s`` from touchdown to disarm; ``ret_s`` holds the return from every waypoint
    (what a dropped tail leaves), ``returns`` the return from anywhere (``ReturnModel``)."""
    kin = spec.kinematics()
    w = spec.waypoints_enu()
    n = len(w)
    rtl = spec.return_behaviour == "rtl"
    returns = ReturnModel.of(
        spec, speed_mps=return_speed_mps if rtl else None, vertical=vertical, disarm_s=disarm_s
    )
    out = spec.flight_path_enu()[: n + 2]  # home, the climb and the waypoints
    tail, tail_speeds, j_tail = returns.legs(w[-1])
    speeds = np.concatenate(
        [leg_speeds(np.diff(out, axis=0), kin, vertical, kin.cruise_speed_mps)[0], tail_speeds]
    )
    path = np.vstack([out, tail[1:]])
    L = np.linalg.norm(np.diff(path, axis=0), axis=1)
    keep = L > 1e-6
    prof = plan_profile(path[np.concatenate([[True], keep])], kin, speeds=speeds[keep])
    s_path = np.concatenate([[0.0], np.cumsum(L)])
    t = np.interp(s_path, prof.s_vertex, prof.t_vertex)
    # the final descent starts j_tail legs after the last waypoint
    t_wp, land = t[2 : 2 + n], float(t[-1] - t[n + 1 + j_tail]) + returns.after_s
    duration = prof.duration_s + returns.after_s
    ret = np.full(n, duration - land - t_wp[-1])
    # from waypoint i straight back over home (after the climb to the return altitude)
    if rtl:
        for i in range(n - 1):
            ret[i] = returns.split(w[i])[0]
    home = np.asarray(spec.home_enu, dtype=float)[:2]
    u_wp = np.vstack([np.zeros((1, 2)), _unit(np.diff(w[:, :2], axis=0))])
    u_ret = _unit(home - w[:, :2]) if rtl else np.zeros((n, 2))
    return BudgetPlan(
        float(spec.time_budget_s), t_wp, duration, land, ret, disarm_s, returns, u_wp, u_ret
    )


def _unit(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to unit length (zero rows stay zero)."""
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v, dtype=float), where=n > 1e-9)


@dataclass
class BudgetWatch:
    """Measured waypoint times against the plan; ``update`` returns the warning text once, when due;
    ``decide`` what the mission's ``policy`` does about a prediction past the budget less
    ``reserve_s``."""

    plan: BudgetPlan
    reached_at: list[float] = field(default_factory=list)  # elapsed s when waypoint k was reached
    predicted_s: float | None = None
    warned_at_s: float | None = None
    predicted_at_warning_s: float | None = None
    policy: str = "warn"
    reserve_s: float = 0.0
    last: int = -1  # the last waypoint kept (-1: all); lowered when the tail is dropped
    prior: Pace | None = None  # the autopilot's known pace until MIN_FIT_LEGS legs are measured
    dropped: list[int] = field(default_factory=list)  # waypoints dropped (0-based here), sorted
    actions: list[dict] = field(default_factory=list)  # what the policy did, when (sidecar)

    def __post_init__(self) -> None:
        if self.last < 0:
            self.last = len(self.plan.t_wp) - 1

    def planned_s(self) -> float:
        """The plan's arm-to-disarm seconds at the autopilot's known pace (``prior``; the kinematic
        plan without one): the one plan figure printed before and after the flight."""
        if self.prior is None:
            return float(self.plan.duration_s)
        return BudgetWatch(self.plan, prior=self.prior).predict(0.0)

    def pace(self) -> float:
        k = len(self.reached_at) - 1
        if k < 1:
            return 1.0
        planned = self.plan.t_wp[k] - self.plan.t_wp[0]
        flown = self.reached_at[k] - self.reached_at[0]
        # several at once: no pace
        return flown / planned if planned >= MIN_PACE_S and flown > 0 else 1.0

    def pace_model(self) -> Pace:
        """The pace of the legs flown so far: fitted per leg from ``MIN_FIT_LEGS`` measured legs
        (waypoints reached together count as one segment), else the autopilot's known ``prior``,
        else the plain ratio (``pace``)."""
        r, t = np.asarray(self.reached_at), self.plan.t_wp[: len(self.reached_at)]
        early = self.prior or Pace(self.pace(), 0.0)
        if len(r) < 2 or t[-1] - t[0] < MIN_PACE_S:
            return early
        ends = np.flatnonzero(np.diff(r) > 0) + 1  # a segment ends where a new arrival time starts
        starts = np.concatenate([[0], ends[:-1]])
        if len(ends) < MIN_FIT_LEGS:
            return early
        # each segment's planned seconds along east and north (the headwind's regressors)
        along = np.cumsum(np.diff(t)[:, None] * self.plan.u_wp[1 : len(t)], axis=0)
        along = np.vstack([np.zeros((1, 2)), along])
        dirs = along[ends] - along[starts]
        return fit_pace(t[ends] - t[starts], ends - starts, r[ends] - r[starts], dirs)

    def predict(self, elapsed: float, last: int | None = None) -> float:
        """Predicted arm-to-disarm seconds given what was measured up to ``elapsed``, the mission
        ending at waypoint ``last`` (default: the last one kept)."""
        p, k = self.plan, min(len(self.reached_at), self.last + 1) - 1
        last = self.last if last is None else last
        pace = self.pace_model()
        # the landing, hover and disarm at the plan's own time (vertical: not slowed)
        tail = p.land_s

        def rest(i: int) -> float:  # from waypoint i (reached) to the end
            legs = np.diff(p.t_wp[i : last + 1])
            back = pace.legs(np.array([p.ret_s[last]]), p.u_ret[last : last + 1])
            return pace.legs(legs, p.u_wp[i + 1 : last + 1]) + back + tail

        if k < 0:
            pred = max(elapsed, pace.legs(p.t_wp[:1])) + rest(0)  # take-off and transit: a leg
        else:
            pred = self.reached_at[k] + rest(k)
            if k + 1 <= last:  # the next waypoint is not reached yet: at least the rest after it
                pred = max(pred, elapsed + rest(k + 1))
        return float(max(pred, elapsed))

    def update(self, elapsed: float, reached: int) -> str | None:
        """``reached`` waypoints were reached by ``elapsed`` (s since arming); the warning text
        once, when the predicted landing time first passes the budget."""
        while len(self.reached_at) < min(reached, len(self.plan.t_wp)):
            self.reached_at.append(elapsed)
        self.predicted_s = self.predict(elapsed)
        b = self.plan.budget_s
        if self.warned_at_s is not None or self.predicted_s <= b - (
            self.reserve_s if self.policy != "warn" else 0
        ):
            return None
        self.warned_at_s, self.predicted_at_warning_s = elapsed, self.predicted_s
        if elapsed > b:
            return f"over the time budget: {elapsed:.0f} s flown of {b:.0f} s, still flying"
        act = {"trim": ": dropping the tail", "return": ": returning"}.get(self.policy, "")
        what = (
            "budget will not hold"
            if self.predicted_s > b
            else f"inside the {self.reserve_s:g} s reserve"
        )
        return (
            f"{what}: landing at ~{self.predicted_s:.0f} s of {b:.0f} s "
            f"(pace {self.pace():.2f}, {len(self.reached_at)}/{len(self.plan.t_wp)} wp){act}"
        )

    def keep_until(self, elapsed: float) -> int:
        """The last waypoint to keep so that the predicted landing is inside the budget less the
        reserve: the largest that fits, at least the one being flown to (the vehicle is on its
        way)."""
        lo = min(len(self.reached_at), self.last)
        limit = self.plan.budget_s - self.reserve_s
        for j in range(self.last, lo, -1):
            if self.predict(elapsed, j) <= limit:
                return j
        return lo

    def decide(self, elapsed: float) -> tuple[str, int] | None:
        """What the policy does now: ("trim", last waypoint kept) when the tail must go and the
        vehicle is within ``TRIM_LOOKAHEAD`` waypoints of the cut; ("return", -1) at once under
        ``return``; None otherwise."""
        if self.predicted_s is None or self.predicted_s <= self.plan.budget_s - self.reserve_s:
            return None
        if self.policy == "return" and not any(a["action"] == "return" for a in self.actions):
            return "return", -1
        if self.policy != "trim":
            return None
        keep = self.keep_until(elapsed)
        if keep < self.last and keep - len(self.reached_at) < TRIM_LOOKAHEAD:
            return "trim", keep
        return None

    def apply(self, elapsed: float, action: str, keep: int) -> str:
        """Record ``action`` (after the autopilot took it); the one line that names what was
        done."""
        b, before = self.plan.budget_s, self.predicted_s
        if action == "return":
            self.actions.append(
                {"t_s": round(elapsed, 1), "action": "return", "predicted_s": round(before, 1)}
            )
            return f"budget: returning to launch now (landing was ~{before:.0f} s of {b:.0f} s)"
        gone = list(range(keep + 1, self.last + 1))
        # the tail, whole, whatever the order of the cuts
        self.dropped = sorted(self.dropped + gone)
        self.last = keep
        self.predicted_s = self.predict(elapsed)
        self.actions.append(
            {
                "t_s": round(elapsed, 1),
                "action": "trim",
                "dropped": [i + 1 for i in gone],  # 1-based, as printed and as dropped_waypoints
                "predicted_before_s": round(before, 1),
                "predicted_s": round(self.predicted_s, 1),
            }
        )
        which = f"{gone[0] + 1}" if len(gone) == 1 else f"{gone[0] + 1}-{gone[-1] + 1}"
        return (
            f"budget: dropped waypoint{'s' if len(gone) > 1 else ''} {which} of "
            f"{len(self.plan.t_wp)}: "
            f"landing ~{self.predicted_s:.0f} s, was ~{before:.0f} s"
        )

    def record(self, used_s: float | None) -> dict:
        """The sidecar's ``budget``: planned vs used seconds, overrun flag and amount, when it was
        warned, the policy and what it dropped: waypoint numbers in the sidecar count from 1, as
        printed (``dropped_waypoints`` and each action's ``dropped``)."""
        b = self.plan.budget_s
        r2 = lambda v: None if v is None or not np.isfinite(v) else round(float(v), 2)  # noqa: E731
        over = used_s is not None and used_s > b
        fitted = self.pace_model() if self.reached_at else None
        return {
            "budget_s": b,
            "planned_s": r2(self.planned_s()),
            "kinematic_plan_s": r2(self.plan.duration_s),
            "used_s": r2(used_s),
            "overrun": bool(over),
            "overrun_s": r2(used_s - b) if over else 0.0,
            "warned_at_s": r2(self.warned_at_s),
            "predicted_at_warning_s": r2(self.predicted_at_warning_s),
            "policy": self.policy,
            "reserve_s": self.reserve_s,
            "pace_prior": None if self.prior is None else _pace_list(self.prior),
            "pace_fitted": None if fitted is None else _pace_list(fitted),
            # extra seconds per planned second flown east / north: where the wind comes from
            "pace_headwind": None if fitted is None else [round(h, 3) for h in fitted.headwind],
            "dropped_waypoints": [i + 1 for i in self.dropped],
            "actions": self.actions,
        }


def _pace_list(p: Pace) -> list[float]:
    return [round(p.scale, 3), round(p.per_leg_s, 2)]


def used_seconds(events: list[dict], t_start: float | None, t_now: float) -> float | None:
    """Arm-to-disarm seconds on the vehicle's clock from the flight's events (to now if not
    disarmed)."""
    arm = next(
        (e["t_vehicle_s"] for e in events if e["kind"] == "armed" and e["t_vehicle_s"] is not None),
        t_start,
    )
    if arm is None:
        return None
    off = [
        e["t_vehicle_s"] for e in events if e["kind"] == "disarmed" and e["t_vehicle_s"] is not None
    ]
    end = off[-1] if off and off[-1] > arm else t_now
    return float(end - arm) if np.isfinite(end) else None


def arm_to_disarm_s(events: list[dict]) -> float | None:
    """Arm to disarm on the vehicle's clock, measured only: None when no disarm after the arm was
    seen."""
    arm = next(
        (e["t_vehicle_s"] for e in events if e["kind"] == "armed" and e["t_vehicle_s"] is not None),
        None,
    )
    off = [
        e["t_vehicle_s"] for e in events if e["kind"] == "disarmed" and e["t_vehicle_s"] is not None
    ]
    return round(float(off[-1] - arm), 2) if arm is not None and off and off[-1] > arm else None


# A flight that stalls is brought home whatever the budget policy: no waypoint reached by this many
# times the plan's time to the first one plus a margin (a take-off that does not climb: PX4 SITL's
# SIH once lost its baro and compass after "Takeoff detected", sat at 0 m in a failsafe and the run
# logged 1 900 s of "takeoff" until it was killed), or the budget overrun by a quarter, at least a
# minute, with no return begun (vehicle seconds since arming)
STALL_FACTOR, STALL_MARGIN_S = 3.0, 60.0
OVERDUE_SHARE, OVERDUE_MIN_S = 0.25, 60.0
TAKEOFF_STALLED, OVERDUE = "take-off stalled", "overdue"  # abort reasons: a failure, exit 3


def stalled(plan: BudgetPlan, elapsed: float, reached: int) -> str | None:
    """Why the flight must be brought home now (one line), or None: no waypoint reached long after
    the plan's first, or far past the budget with no return begun."""
    first = float(plan.t_wp[0]) if len(plan.t_wp) else 0.0
    if reached == 0 and elapsed > STALL_FACTOR * first + STALL_MARGIN_S:
        return (
            f"{TAKEOFF_STALLED}: no waypoint reached {elapsed:.0f} s after arming (plan: the "
            f"first at {first:.0f} s)"
        )
    late = max(OVERDUE_MIN_S, OVERDUE_SHARE * plan.budget_s)
    if elapsed > plan.budget_s + late:
        return f"{OVERDUE}: {elapsed:.0f} s after arming, budget {plan.budget_s:.0f} s"
    return None


def arrival_time(tel, origin, wp_enu: np.ndarray, since: float, t_event: float) -> float:
    """Vehicle time at which the position track (``tel.pos``, after ``since``, up to
    ``t_event``) passed closest to the waypoint; ``t_event`` when it never came within
    ``ARRIVAL_RADIUS_M``.

    Why: the progress message is timed when the runner reads it, which a loaded machine or a slow
    link delays, by the speed-up times as much on a SITL; the positions carry the vehicle's own
    clock.  ArduCopter SITL at 20x read one arrival 2.55 s late: the pace fit took it for a cost
    per leg, predicted 595 s for a 574 s flight and would have dropped its last waypoint."""
    t, v = tel.pos.window(since, t_event)
    if not len(t):
        return t_event
    d = np.hypot(*(origin.to_enu(v[:, 0], v[:, 1])[:, :2] - np.asarray(wp_enu)[:2]).T)
    k = int(np.argmin(d))
    return float(t[k]) if d[k] <= ARRIVAL_RADIUS_M else t_event


def _reached(phase: str, item: int, n: int) -> int | None:
    """Waypoints reached when the phase tracker says ``phase``/``item`` (None: no mission progress
    yet)."""
    if phase == "mission":
        return max(item, 0)
    return n if phase in ("adaptive", "return", "land") else None


async def watch_budget(ctx, watch: BudgetWatch, mission_raw=None, action=None) -> None:
    """Task: every 0.25 s compare the flight's progress with the plan; warn once (line + ``budget``
    event) and let the policy act (``act``: needs ``mission_raw`` and ``action``).  Waypoint times
    are where the track passed closest to them (``arrival_time``), else the vehicle times at which
    the progress arrived (``ctx.phases``), never the poll's."""
    s, ph, seen, reached = ctx.status, ctx.phases, 1, 0
    wps, t_prev = ctx.spec.waypoints_enu(), -np.inf
    while not ctx.landed_disarmed.is_set():
        await asyncio.sleep(0.25)
        if ctx.abort.is_set() or getattr(ph, "returning", False):
            return  # a commanded return (Ctrl-C, a failure) ends the plan: nothing left to predict
        if s.t_start is None or not np.isfinite(s.t_start):
            continue
        steps = [(ph.t[i], ph.phase[i], ph.item[i]) for i in range(seen, len(ph.t))]
        seen += len(steps)
        texts = []
        for t, phase, item in steps:
            if (r := _reached(phase, item, watch.last + 1)) is not None and r > reached:
                reached = r
                since = max(t_prev, s.t_start)
                t_prev = t = arrival_time(ctx.tel, ctx.spec.field.origin, wps[r - 1], since, t)
                texts.append(watch.update(max(t - s.t_start, 0.0), reached))
        texts.append(watch.update(s.elapsed, reached))
        home = ph.current in (RETURN, LAND)  # the mission's own return: not stalled
        if not home and (why := stalled(watch.plan, s.elapsed, reached)):
            ctx.abort_for(why.split(":", 1)[0], f"{why}: returning to launch", warn=True)
            return
        if not getattr(ctx.extension, "rounds", None):  # adaptive rounds: land~ is their plan
            s.predicted_s = watch.predicted_s
        for text in filter(None, texts):
            ctx.event("budget", text, warn=True)
        if mission_raw is not None and (d := watch.decide(s.elapsed)) is not None:
            await act(ctx, watch, d, mission_raw, action)
            s.predicted_s = watch.predicted_s


async def act(ctx, watch: BudgetWatch, decision: tuple[str, int], mission_raw, action) -> None:
    """Carry out ``decision`` (``BudgetWatch.decide``) on the autopilot: the mission re-uploaded
    without its dropped tail (the current item kept: items already flown keep their indices), or
    return to launch.  A failed upload leaves the whole mission (safe, over budget) and says so."""
    what, keep = decision
    s = ctx.status
    if what == "return":
        ctx.phases.on_return(ctx.tel.clock.now())
        await action.return_to_launch()
        ctx.event("budget", watch.apply(s.elapsed, what, keep), warn=True)
        return
    spec, home, off = ctx.spec, ctx.home, s.waypoint_offset
    w = spec.waypoints_enu()[: keep + 1]
    items = build_items(
        dataclasses.replace(spec, trajectory=TrajectorySpec("waypoints", {}, w)),
        (home.latitude_deg, home.longitude_deg, home.absolute_altitude_m),
        off == 3,
    )
    cur = ctx.st.progress[0]
    try:
        await upload_with_retries(ctx, mission_raw, items, kind="budget")
        await mission_raw.set_current_mission_item(max(cur, ctx.phases.raw_item))
    except Exception as e:
        watch.policy = "warn"  # the autopilot keeps the whole mission
        why = str(e) if str(e) and len(str(e)) < 60 else type(e).__name__
        ctx.event("budget", f"could not drop the mission's tail ({why}): flying it all", warn=True)
        return
    ctx.phases.configure(off, len(items) - 1, ctx.phases.final)
    s.n_waypoints = keep + 1
    ctx.event("budget", watch.apply(s.elapsed, what, keep), warn=True)


def start_budget(
    ctx,
    return_speed_mps: float | None,
    vertical: VerticalSpeeds | None,
    ardupilot: bool | None = None,
) -> BudgetWatch:
    """The watch of ``ctx``'s flight, planned with the return, climb and descent speeds the
    autopilot will fly and its known touchdown-to-disarm delay (``ardupilot`` True/False for a
    connected autopilot, None for the built-in vehicle); one line with that plan, a warning before
    take-off when it no longer fits the budget. An adaptive flight's rounds are planned against the
    budget by the round planner: its survey is only watched."""
    spec = ctx.spec
    own = return_speed_mps is not None and abs(return_speed_mps - spec.cruise_speed_mps) > 1e-6
    builtin = ardupilot is None or not ctx.url or getattr(ctx, "builtin_vehicle", False)
    known = None if builtin else ("ARDUPILOT" if ardupilot else "PX4")
    adaptive = ctx.extension is not None
    watch = BudgetWatch(
        plan_times(
            spec, return_speed_mps if own else None, vertical, LANDED_TO_DISARM_S.get(known, 0.0)
        ),
        policy="warn" if adaptive else spec.budget_policy,
        reserve_s=spec.budget_reserve_s,
        prior=PACE_PRIOR.get(known),
    )
    d, b = watch.planned_s(), spec.time_budget_s
    how = [f"return {return_speed_mps:g}"] if own else []
    # one line at 80 columns: "plan 565 s of 600 s (autopilot m/s: up 2.5, ...)"
    if vertical is not None:
        v = vertical
        slow = (
            f"/{v.land_mps:g} below {v.low_alt_m:g} m"
            if v.low_alt_m > 0 and v.land_mps != v.down_mps
            else ""
        )
        how.append(
            f"up {v.up_mps:g}, down {v.down_mps:g}{slow}"
            + (f", hover {v.hover_s:g} s" if v.hover_s else "")
        )
    p = watch.prior
    pace = f", {known} pace {p.scale:g} x + {p.per_leg_s:g} s a leg" if p else ""
    text = (
        ("survey " if adaptive else "")
        + f"plan {d:.0f} s of {b:g} s"
        + (f" (autopilot m/s: {'; '.join(how)}{pace})" if how else f" ({pace[2:]})" if p else "")
    )
    ctx.event("budget", text + (f": {d - b:.0f} s over budget" if d > b else ""), warn=d > b)
    return watch


def close_budget(ctx, watch: BudgetWatch) -> dict:
    """The sidecar record, and one line: used vs budget (a warning when over)."""
    # no disarm seen: no
    now = ctx.tel.clock.now() if ctx.landed_disarmed.is_set() else float("nan")
    used = used_seconds(ctx.st.events, ctx.status.t_start, now)  # extrapolated time (a lost link)
    rec = watch.record(used)
    rec["arm_to_disarm_s"] = arm_to_disarm_s(ctx.st.events)
    if used is not None:
        # an adaptive flight: survey and rounds apart
        rounds = getattr(ctx.extension, "flown_s", None)
        plan = (
            f"plan {rec['planned_s']:.0f} s"
            if rounds is None
            else f"survey plan {rec['planned_s']:.0f} s, rounds flew {rounds:.0f} s"
        )
        text = f"flight used {used:.0f} s of its {rec['budget_s']:.0f} s budget ({plan})"
        if rec["overrun"]:
            text += f": {rec['overrun_s']:.0f} s over"
        ctx.event("budget", text, warn=rec["overrun"])
    return rec
