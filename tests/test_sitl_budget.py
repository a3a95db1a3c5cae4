"""The flight's time budget: the plan per waypoint, the prediction from measured progress, one
warning as soon as the remaining plan cannot fit, the sidecar record; speed parameters set and
restored."""

from __future__ import annotations

import asyncio
from pathlib import Path

import numpy as np
import pytest

from mission.flight.ardupilot import set_params
from mission.flight.budget import BudgetWatch, plan_times, used_seconds
from mission.flight.heartbeat import heartbeat_hz
from mission.flight.speeds import speed_params
from mission.spec import load_mission
from mission.trajectory.autopilot import VerticalSpeeds
from mission.trajectory.checks import check_mission

SPIRAL = Path(__file__).resolve().parents[1] / "missions" / "spiral.yaml"


@pytest.fixture(scope="module")
def spec():
    return load_mission(SPIRAL)


def test_plan_times_is_the_preflight_plan(spec):
    p = plan_times(spec)
    assert p.duration_s == pytest.approx(check_mission(spec).duration_s, abs=1e-6)
    assert len(p.t_wp) == len(spec.waypoints_enu()) and np.all(np.diff(p.t_wp) > 0)
    assert 0 < p.t_wp[0] < p.t_wp[-1] < p.duration_s
    # PX4's own return speed: only the return is longer
    slow = plan_times(spec, return_speed_mps=4.8)
    # the last corner slows for the slower leg
    np.testing.assert_allclose(slow.t_wp, p.t_wp, atol=0.1)
    back = float(np.hypot(*(spec.waypoints_enu()[-1, :2] - np.asarray(spec.home_enu)[:2])))
    assert slow.duration_s - p.duration_s == pytest.approx(back / 4.8 - back / 5.5, rel=0.15)


def _fly(watch: BudgetWatch, pace: float, stop_at: int | None = None, dt: float = 0.5):
    """Feed the watch a flight flown ``pace`` times slower than planned (stalled after
    ``stop_at``)."""
    p, warned = watch.plan, None
    for e in np.arange(0.0, p.duration_s * pace, dt):  # the task stops at landing
        reached = int(np.sum(p.t_wp * pace <= e))
        if stop_at is not None:
            reached = min(reached, stop_at)
        if (text := watch.update(float(e), reached)) is not None:
            assert warned is None  # once
            warned = (float(e), text)
    return warned


def test_on_plan_no_warning_and_prediction_is_the_plan(spec):
    w = BudgetWatch(plan_times(spec))
    assert _fly(w, 1.0) is None
    assert w.predicted_s == pytest.approx(w.plan.duration_s, rel=0.01)
    w2 = BudgetWatch(plan_times(spec))
    w2.update(300.0, 9)  # nine waypoints at once (no measured pace): the plan's remaining time
    assert w2.predicted_s == pytest.approx(300.0 + w2.plan.duration_s - w2.plan.t_wp[8])


def test_slow_autopilot_warned_early_with_an_honest_prediction(spec):
    """PX4 flew 7 % slower: 539 s * 1.07 = 577 s fits 600 s, but not 560 s; the warning comes after
    the first 30 s of mission legs, long before the budget is used up, predicting the true landing
    within 2 %."""
    plan = plan_times(spec)
    assert _fly(BudgetWatch(plan), 1.07) is None
    plan.budget_s = 560.0
    w = BudgetWatch(plan)
    at, text = _fly(w, 1.07)
    assert at < 0.3 * plan.duration_s and "budget will not hold" in text and "560 s" in text
    assert w.predicted_at_warning_s == pytest.approx(plan.duration_s * 1.07, rel=0.02)
    rec = w.record(577.0)
    assert (
        rec["overrun"] is True
        and rec["overrun_s"] == pytest.approx(17.0)
        and rec["warned_at_s"] == at
    )
    assert w.record(550.0)["overrun"] is False and w.record(550.0)["overrun_s"] == 0.0


def test_a_stalled_vehicle_is_warned_before_the_budget_runs_out(spec):
    plan = plan_times(spec)
    w = BudgetWatch(plan)
    at, text = _fly(w, 1.0, stop_at=5)  # holding after waypoint 5
    assert at < plan.budget_s and "will not hold" in text and len("WARNING: " + text) <= 80


def test_used_seconds_arm_to_disarm():
    ev = [
        {"kind": "armed", "t_vehicle_s": 20.0},
        {"kind": "statustext", "t_vehicle_s": 30.0},
        {"kind": "disarmed", "t_vehicle_s": 606.0},
    ]
    assert used_seconds(ev, 21.0, 700.0) == pytest.approx(586.0)
    assert used_seconds(ev[:2], 21.0, 700.0) == pytest.approx(680.0)  # not disarmed: to now
    assert used_seconds([], None, 5.0) is None


def test_heartbeat_rate_follows_the_speedup():
    """Three ground-station heartbeats per vehicle second: PX4's 2.5 s gate stays open at any
    speed-up."""
    for su in (1, 5, 10, 20):
        assert heartbeat_hz(su) == 3 * su and su / heartbeat_hz(su) <= 0.34
    assert heartbeat_hz(0.5) == 1.5 and heartbeat_hz(0.1) == 1.0


class _Params:
    """MAVSDK's ParamAsync surface (get/set int and float) over a dict, to check what is set and
    restored."""

    def __init__(self, values):
        self.values, self.sets = dict(values), []

    async def get_param_int(self, n):
        return int(self.values[n])

    async def get_param_float(self, n):
        return float(self.values[n])

    async def set_param_int(self, n, v):
        assert isinstance(v, int)
        self.sets.append((n, v))
        self.values[n] = v

    async def set_param_float(self, n, v):
        assert isinstance(v, float)
        self.sets.append((n, v))
        self.values[n] = v


def test_speed_params_set_and_restored_on_both_autopilots():
    assert speed_params(False, 5.5) == {"MPC_XY_CRUISE": 5.5}
    assert speed_params(True, 5.5) == {"WP_YAW_BEHAVIOR": 1, "RTL_SPEED": 550}
    for ardupilot, own in (
        (False, {"MPC_XY_CRUISE": 4.8}),
        (True, {"WP_YAW_BEHAVIOR": 2, "RTL_SPEED": 0}),
    ):
        p = _Params(own)
        old = asyncio.run(set_params(p, speed_params(ardupilot, 5.5)))
        assert old == own and p.values == speed_params(ardupilot, 5.5)
        asyncio.run(set_params(p, old))
        assert p.values == own
    p = _Params({"MPC_XY_CRUISE": 5.5})
    # already so: untouched
    assert asyncio.run(set_params(p, {"MPC_XY_CRUISE": 5.5})) == {} and p.sets == []


def test_plan_with_the_autopilots_take_off_and_landing_speeds(spec):
    """ArduCopter lands at 1.5 m/s, then 0.5 m/s below 10 m: 20/1.5 + 10/0.5 = 33 s where the
    mission's kinematics plan 30/2.5 = 12 s; PX4 climbs at 1.5 m/s (20 s, not 12).  Waypoint times
    move only by the take-off difference."""
    base = plan_times(spec)
    ap = plan_times(spec, vertical=VerticalSpeeds(2.5, 1.5, 0.5, 10.0))
    np.testing.assert_allclose(ap.t_wp, base.t_wp, atol=1e-6)
    assert ap.duration_s - base.duration_s == pytest.approx(20 / 1.5 + 10 / 0.5 - 30 / 2.5, abs=2.0)
    px4 = plan_times(spec, vertical=VerticalSpeeds(1.5, 1.5, 0.7, 5.0))
    np.testing.assert_allclose(px4.t_wp - base.t_wp, 30 / 1.5 - 30 / 2.5, atol=1.0)
    assert not VerticalSpeeds(0.0, 1.0, 1.0, 0.0).valid()


def test_hover_before_landing_is_reserved_outside_the_pace(spec):
    """ArduCopter hovers RTL_LOIT_TIME (5 s) over home before landing: planned, and like the landing
    not stretched by a slow cruise."""
    v = VerticalSpeeds(2.5, 1.5, 0.5, 10.0)
    a, b = (
        plan_times(spec, vertical=v),
        plan_times(spec, vertical=VerticalSpeeds(2.5, 1.5, 0.5, 10.0, 5.0)),
    )
    assert b.duration_s - a.duration_s == pytest.approx(
        5.0
    ) and b.land_s - a.land_s == pytest.approx(5.0)
    assert a.land_s == pytest.approx(20 / 1.5 + 10 / 0.5, abs=2.0)
    w = BudgetWatch(b)
    w.update(0.0, 0)
    w.update(b.t_wp[0], 1)
    k = int(np.searchsorted(b.t_wp, 100.0))
    w.update(b.t_wp[k] * 1.1, k + 1)  # 10 % slow so far
    assert w.predicted_s == pytest.approx(
        b.t_wp[k] * 1.1 + (b.duration_s - b.land_s - b.t_wp[k]) * w.pace() + b.land_s
    )
