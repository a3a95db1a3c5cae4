"""The budget watch's pace fit replayed on flown SITL spirals with one leg made slow (a gust), and
on spirals flown in wind: least squares from four legs (before 2026-11-29), a robust fit from six
(the first change, withdrawn) and today's robust fit with the headwind from ``MIN_FIT_LEGS``.

    python benchmarks/replay_pace.py STORE/*_fixed_*/flights/*/flight.csv

Why: a leg flown a few seconds slow delays every later arrival by as much, and nothing more; a
least-squares fit of flown = scale x planned + cost per leg on a few legs took it for a cost on
every leg to come and predicted the landing 18 s late (waypoint 3 reached 2.55 s late, six
reached), enough to drop the spiral's tail.  A wind slows the upwind legs only.  Each log's
arrivals are timed where its track passed closest to each waypoint (``arrival_time``, as the runner
does); then each leg in turn is made ``d`` s slow (every later arrival ``d`` s later).  The watch is
the runner's (``trim``, 10 s reserve, the autopilot's climb, landing, disarm delay and known pace).
Reported per fit and slow leg: the largest over- and under-prediction of the landing after the fit
starts (predicted for the mission ending where the flight ended, less its arm-to-disarm time and
``d``; over waypoints, slow legs and flights) and how many replays the policy cut beyond what the
flight itself did although the slowed flight would still have landed inside the budget less its
reserve; and the spread of the legs about each flight's own fit (what ``PACE_FIT_SCALE_S`` is set
to).

Rule 1 (2026-11-29 03:29 UTC, in a working file before the second wind's flights 45-47 were
scored; flown by ``fly_windy.py --wind 6 30 2 --seeds 44 45 46 47``): the pace fit becomes
direction-aware (robust, headwind, from 8 legs) if on those windy flights its worst
under-prediction is no worse than least squares from 4 legs and its worst over-prediction no worse
than least squares', and on the stored calm ArduCopter (38) and PX4 (35) spirals neither figure is
worse by more than 1 s; otherwise revert to least squares from 4 legs.  Result: -2.7 / -5.3 s
against -0.5 / -5.2 s: under-prediction worse by 0.1 s, refused (a wind too mild to move the legs).

Rule 2 (03:31 UTC, after rule 1's result, before any of its flights): fresh seeds 48-51,
``fly_windy.py --wind 9 140 3``.  Adopt if (a) its worst under-prediction is within 1 s of least
squares' or better, (b) its worst over-prediction is within 1 s of least squares' or better, (c) its
worst miss max(over, -under) is smaller than least squares', and calm flights as in rule 1.
Result: -5.0 / -19.5 s against 9.2 / -28.1 s (worst miss 19.5 against 28.1 s); calm ArduCopter
-2.7 / -4.7 against -1.7 / -4.7 s, PX4 4.7 / -8.1 against 12.5 / -13.6 s: adopted.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from replay_arrivals import ARDUCOPTER, track_and_messages  # noqa: E402

from mission.flight import budget  # noqa: E402
from mission.flight.budget import (  # noqa: E402
    LANDED_TO_DISARM_S,
    PACE_PRIOR,
    BudgetWatch,
    arrival_time,
    plan_times,
)
from mission.flightlog import read_flight_log  # noqa: E402
from mission.spec import load_mission  # noqa: E402
from mission.trajectory.autopilot import VerticalSpeeds  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PX4 = VerticalSpeeds(1.5, 1.5, 0.7, 5.0, 0.0, 30.0)  # PX4 v1.16 SITL's defaults (test_returns.py)
# (label, Huber scale s, legs before the fit, headwind fitted): inf scale is least squares; None:
# today's value.  The first is the fit before 2026-11-29, the second the same day's first change.
FITS = (
    ("least squares, 4 legs", np.inf, 4, False),
    ("robust, 6 legs", 0.1, 6, False),
    ("robust+headwind, 8 legs", None, None, True),
)


def arrivals(spec, log) -> tuple[np.ndarray, float]:
    """Seconds after arming at which the flown spiral reached each waypoint (by the track), and its
    arm-to-disarm seconds."""
    wps, origin = spec.waypoints_enu(), spec.field.origin
    tel, armed, sent = track_and_messages(log)
    t, t_prev = [], -np.inf
    for r, t_msg in enumerate(sent):
        t_prev = arrival_time(tel, origin, wps[r], max(t_prev, armed), t_msg)
        t.append(t_prev - armed)
    return np.asarray(t), float(log.meta["budget"]["used_s"])


def replay(plan, prior, t_arr: np.ndarray, used_s: float) -> tuple[float, float, int]:
    """(largest over- and under-prediction of the landing once the pace is fitted, the last
    waypoint kept) of the watch fed ``t_arr``; the prediction is for the mission ending where the
    flight ended (its last arrival), against its arm-to-disarm ``used_s``."""
    w = BudgetWatch(plan, policy="trim", reserve_s=10.0, prior=prior)
    over, under, end = -np.inf, np.inf, len(t_arr) - 1
    for r, t in enumerate(t_arr, start=1):
        w.update(float(t), r)
        if r > budget.MIN_FIT_LEGS:
            miss = w.predict(float(t), end) - used_s
            over, under = max(over, miss), min(under, miss)
        if (d := w.decide(float(t))) is not None:
            w.apply(float(t), *d)
    return over, under, w.last


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="+", type=Path, help="flight.csv of fixed SITL spirals")
    ap.add_argument("--slow", nargs="+", type=float, default=[0.0, 1.0, 2.55, 5.0])
    args = ap.parse_args(argv)
    spec = load_mission(ROOT / "missions" / "spiral.yaml")
    plans = {
        "ARDUPILOT": (plan_times(spec, None, ARDUCOPTER, LANDED_TO_DISARM_S["ARDUPILOT"]), None),
        "PX4": (plan_times(spec, None, PX4, LANDED_TO_DISARM_S["PX4"]), PACE_PRIOR["PX4"]),
    }
    flights = {}
    for p in args.logs:
        log = read_flight_log(p)
        if (ap_ := log.meta.get("autopilot")) in plans and log.meta["budget"]["used_s"]:
            flights.setdefault(ap_, []).append(arrivals(spec, log))
    scale0, legs0 = budget.PACE_FIT_SCALE_S, budget.MIN_FIT_LEGS
    for ap_, rows in sorted(flights.items()):
        prior = plans[ap_][1]
        print(f"{ap_}: {len(rows)} spirals, each leg in turn made slow")
        print("  fit                      slow s  worst over / under s  needless cuts")
        for label, scale, legs, headwind in FITS:
            budget.PACE_FIT_SCALE_S = scale0 if scale is None else scale
            budget.MIN_FIT_LEGS = legs0 if legs is None else legs
            plan = plans[ap_][0]
            if not headwind:  # no leg directions: the headwind's columns vanish from the fit
                zero = np.zeros_like(plan.u_wp)
                plan = dataclasses.replace(plan, u_wp=zero, u_ret=zero)
            # where each flight, as flown, would have been cut by this fit
            kept = [replay(plan, prior, t_arr, used)[2] for t_arr, used in rows]
            for d in args.slow:
                over, under, more, n = -np.inf, np.inf, 0, 0
                for (t_arr, used), cut in zip(rows, kept, strict=True):
                    for j in range(1, len(t_arr) if d > 0 else 2):
                        shifted = t_arr + d * (np.arange(len(t_arr)) >= j)
                        o, u, last = replay(plan, prior, shifted, used + d)
                        # a cut the slowed flight did not need (it would land inside the reserve)
                        needless = last < cut and used + d <= plan.budget_s - 10.0
                        over, under = max(over, o), min(under, u)
                        more, n = more + needless, n + 1
                print(f"  {label:23}  {d:6.2f}  {over:9.1f} / {under:6.1f}  {more:5d} of {n}")
        budget.PACE_FIT_SCALE_S, budget.MIN_FIT_LEGS = scale0, legs0
        # how far each flight's legs lie from its own fitted pace (all its legs, no headwind)
        spread = []
        for t_arr, _ in rows:
            legs_planned = np.diff(plans[ap_][0].t_wp[: len(t_arr)])
            pace = budget.fit_pace(legs_planned, np.ones(len(legs_planned)), np.diff(t_arr))
            spread.append(np.abs(np.diff(t_arr) - pace.scale * legs_planned - pace.per_leg_s))
        s = np.concatenate(spread)
        print(
            f"  legs about their flight's fit: |residual| median {np.median(s):.2f} s, "
            f"90 % {np.percentile(s, 90):.2f} s"
        )


if __name__ == "__main__":
    main()
