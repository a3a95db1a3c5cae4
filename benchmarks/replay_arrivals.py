"""The budget watch replayed on flown ArduCopter SITL spirals, their progress messages delayed at
random as on a loaded machine: waypoints timed by the messages against timed by the track.

    python benchmarks/replay_arrivals.py STORE/ardupilot_fixed_*/flights/*/flight.csv

Why: a loaded CI run dropped the spiral's last waypoint on ArduCopter SITL at 20x, and a stored
flight (seed 28) read one arrival 2.55 s of vehicle time late, which the pace fit took for a cost
per leg (595 s predicted for a 574 s flight). Each log's own position rows (vehicle clock) are the
track; each waypoint's message time is the row where the log's ``mission_item`` moved on, plus a
delay drawn for 30 % of the arrivals (exponential, of the given mean; seed 0). The watch is the
runner's (``flight.budget``: ``trim``, 10 s reserve), planned with ArduCopter SITL's climb, landing,
hover and disarm (the speeds the runner reads from it). Reported per mean delay: the median and
largest predicted landing over the flights and how many flights the policy would have trimmed
(none need it: they used 573-574 s of 600).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mission.flight.budget import LANDED_TO_DISARM_S, BudgetWatch, arrival_time, plan_times
from mission.flight.telemetry import Telemetry
from mission.flightlog import read_flight_log
from mission.spec import load_mission
from mission.trajectory.autopilot import VerticalSpeeds

ROOT = Path(__file__).resolve().parents[1]
# ArduCopter 4.7 SITL's own speeds as the runner reads them (tests/test_sitl_budget.py)
ARDUCOPTER = VerticalSpeeds(2.5, 1.5, 0.5, 10.0, 5.0, 15.0)
SHARE_DELAYED = 0.3


def track_and_messages(log) -> tuple[Telemetry, float, np.ndarray]:
    """A flown spiral's position track as the runner's telemetry ring, its arming time and the
    vehicle time at which each waypoint's progress message was logged (the last: the return's
    start), all on the vehicle's clock."""
    m = log.meta
    armed = next(e for e in m["events"] if e["kind"] == "armed")["t_vehicle_s"]
    tv = log["t_s"] + m["t0_vehicle_s"]
    tel = Telemetry(m.get("speedup_measured") or 1.0)
    cols = (log["lat_deg"], log["lon_deg"], log["alt_m"], log["rel_alt_m"])
    for t, *row in zip(tv, *cols, strict=True):
        tel.pos.add(float(t), tuple(row))
    phase, item = log.columns["phase"], log.columns["mission_item"]
    n = int(item[phase == "mission"].max()) + 1
    sent = [tv[np.argmax((phase == "mission") & (item >= k))] for k in range(1, n)]
    sent.append(tv[np.argmax(phase == "return")])
    return tel, armed, np.asarray(sent)


def replay(spec, log, rng, mean_delay_s: float, by_track: bool) -> tuple[float, bool]:
    """(the largest predicted landing, whether the policy trimmed) over one flown spiral ``log``
    of mission ``spec``."""
    wps, origin = spec.waypoints_enu(), spec.field.origin
    tel, armed, sent = track_and_messages(log)
    n = len(sent)
    late = rng.exponential(mean_delay_s, n) * (rng.random(n) < SHARE_DELAYED)
    read = np.maximum.accumulate(np.asarray(sent) + late)
    w = BudgetWatch(
        plan_times(spec, None, ARDUCOPTER, LANDED_TO_DISARM_S["ARDUPILOT"]),
        policy="trim",
        reserve_s=10.0,
    )
    t_prev, worst, trimmed = -np.inf, 0.0, False
    for r in range(1, n + 1):
        t = read[r - 1]
        if by_track:
            t = t_prev = arrival_time(tel, origin, wps[r - 1], max(t_prev, armed), t)
        w.update(t - armed, r)
        worst = max(worst, w.predicted_s)
        if (d := w.decide(read[r - 1] - armed)) is not None:
            trimmed = True
            w.apply(read[r - 1] - armed, *d)
    return worst, trimmed


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="+", type=Path, help="flight.csv of ArduCopter SITL spirals")
    ap.add_argument("--delays", nargs="+", type=float, default=[0.0, 2.0, 5.0, 10.0])
    args = ap.parse_args(argv)
    spec = load_mission(ROOT / "missions" / "spiral.yaml")
    logs = [
        log for p in args.logs if (log := read_flight_log(p)).meta.get("autopilot") == "ARDUPILOT"
    ]
    print(f"{len(logs)} ArduCopter SITL spirals; 30 % of arrivals read late")
    print("  mean delay s  timed by  predicted landing median / max s  trimmed")
    for mean in args.delays:
        for by_track in (False, True):
            rng = np.random.default_rng(0)
            res = [replay(spec, log, rng, mean, by_track) for log in logs]
            worst = np.array([r[0] for r in res])
            n_trim = sum(r[1] for r in res)
            who = "track" if by_track else "message"
            print(
                f"  {mean:12.1f}  {who:8}  {np.median(worst):16.1f} / {worst.max():6.1f}"
                f"       {n_trim:3d} of {len(logs)}"
            )


if __name__ == "__main__":
    main()
