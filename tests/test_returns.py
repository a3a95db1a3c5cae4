"""The autopilot's return to launch from anywhere (``trajectory.autopilot.ReturnModel``): closed
forms for the climb to the return altitude and the landing speeds, the budget plan built on it, and
the adaptive round planner that must plan with it (PX4 SITL overran its budget by 13 s when the
rounds planned a return without PX4's climb from 15 to 30 m)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.adaptive.feasibility import adaptive_violations
from mission.adaptive.planner import box_pattern, plan_round, survey_profile
from mission.adaptive.rounds import measured_pace
from mission.flight.budget import PACE_PRIOR, BudgetWatch, plan_times
from mission.spec import load_mission
from mission.trajectory.autopilot import Pace, ReturnModel, VerticalSpeeds
from mission.trajectory.kinematics import Kinematics

ROOT = Path(__file__).resolve().parents[1]
PX4 = VerticalSpeeds(1.5, 1.5, 0.7, 5.0, 0.0, 30.0)  # PX4 v1.16 SITL multicopter defaults


@pytest.fixture(scope="module")
def spec():
    return load_mission(ROOT / "missions" / "spiral_adaptive.yaml")


def _model(**kw) -> ReturnModel:
    return ReturnModel(np.zeros(3), Kinematics(cruise_speed_mps=5.0, accel_mps2=1.5), **kw)


def test_over_home_on_the_ground_nothing_is_left_but_the_disarm():
    assert _model(disarm_s=7.2).seconds(np.zeros(3)) == pytest.approx(7.2)
    assert _model(vertical=PX4).split(np.zeros(3)) == (0.0, 0.0)


def test_a_vertical_landing_takes_the_closed_form_of_the_landing_speeds():
    """'land' at 30 m: 25 m at 1.5 m/s, then 5 m at 0.7 m/s, plus the stops of a trapezoid (each
    leg from rest to rest adds v / a) and the disarm; nothing flies horizontally."""
    m = _model(behaviour="land", vertical=PX4, disarm_s=7.2)
    back, land = m.split(np.array([200.0, -50.0, 30.0]))
    a = 1.5
    closed = 25 / 1.5 + 1.5 / a + 5 / 0.7 + 0.7 / a + 7.2
    assert back == 0.0 and land == pytest.approx(closed, abs=0.05)


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(-400, 400),
    y=st.floats(-400, 400),
    z=st.floats(5.0, 29.0),
)
def test_a_return_from_below_the_return_altitude_climbs_to_it_first(x, y, z):
    """From ``z`` below the 30 m return altitude the return takes the climb (rest to rest at
    1.5 m/s) more than from 30 m at the same place; from above it, nothing changes."""
    m = _model(vertical=PX4)
    low, high = m.seconds(np.array([x, y, z])), m.seconds(np.array([x, y, 30.0]))
    h, v, acc = 30 - z, 1.5, 1.5  # rest to rest: a trapezoid, or a triangle below v^2 / a
    climb = h / v + v / acc if h >= v * v / acc else 2 * np.sqrt(h / acc)
    assert low - high == pytest.approx(climb, abs=0.05)
    flat = _model(vertical=dataclasses.replace(PX4, return_alt_m=0.0))
    assert flat.seconds(np.array([x, y, 40.0])) == m.seconds(np.array([x, y, 40.0]))


def test_the_return_is_symmetric_about_home_and_grows_with_distance():
    m = _model(vertical=PX4, speed_mps=5.5)
    a, b = m.seconds(np.array([300.0, 40.0, 15.0])), m.seconds(np.array([-300.0, -40.0, 15.0]))
    assert a == pytest.approx(b, abs=1e-9)
    far = m.seconds(np.array([600.0, 80.0, 15.0]))
    # the cruise part of 302 m more at 5.5 m/s
    assert far - a == pytest.approx(np.hypot(300.0, 40.0) / 5.5, abs=0.05)


def test_the_pace_stretches_the_flying_back_not_the_landing():
    m = _model(vertical=PX4, disarm_s=7.2)
    frm = np.array([300.0, 0.0, 15.0])
    back, land = m.split(frm)
    assert m.seconds(frm, Pace(1.2, 3.0)) == pytest.approx(1.2 * back + 3.0 + land)


def test_the_budget_plan_returns_from_its_last_waypoint_as_the_model_does(spec):
    """The plan's return and landing from the last waypoint equal the model's from there (the
    join's corner speed aside); a return altitude above the waypoints adds the climb, one at or
    below them changes nothing, bit for bit."""
    s = load_mission(ROOT / "missions" / "spiral.yaml")
    base = plan_times(s, vertical=dataclasses.replace(PX4, return_alt_m=0.0), disarm_s=7.2)
    same = plan_times(s, vertical=PX4, disarm_s=7.2)  # the spiral flies at 30 m
    assert same.duration_s == base.duration_s and np.array_equal(same.ret_s, base.ret_s)
    high = plan_times(s, vertical=dataclasses.replace(PX4, return_alt_m=50.0), disarm_s=7.2)
    np.testing.assert_allclose(high.t_wp, base.t_wp, atol=0.5)  # it stops to climb
    assert high.duration_s - base.duration_s == pytest.approx(20 / 1.5 + 20 / 1.5, abs=2.5)
    end = s.waypoints_enu()[-1]
    model = high.returns.seconds(end)
    assert high.duration_s - high.t_wp[-1] == pytest.approx(model, abs=1.5)


def test_a_round_is_planned_with_the_autopilots_return(spec):
    """The round's return is the autopilot's (climb to 30 m, PX4's landing, disarm); a start that
    fits the full square with the mission's kinematic return no longer does with PX4's."""
    a = spec.adaptive
    start = survey_profile(spec, a.survey_s).vertices[-1]
    px4 = ReturnModel.of(spec, vertical=PX4, disarm_s=7.2)
    kin = plan_round(spec, a, (150.0, 200.0), start, 320.0)
    own = plan_round(spec, a, (150.0, 200.0), start, 320.0, returns=px4)
    wps = box_pattern(np.asarray(own.centre), own.radius_m, a.altitude(spec), start)
    assert own.return_s == pytest.approx(px4.seconds(wps[-1]))
    assert own.return_s - kin.return_s > 15.0  # the climb, the slower landing, the disarm
    t = spec.time_budget_s - a.reserve_s - kin.fly_s - kin.return_s - 1.0
    assert plan_round(spec, a, (150.0, 200.0), start, t).radius_m == a.radius_m
    late = plan_round(spec, a, (150.0, 200.0), start, t, returns=px4)
    assert not late.ok or late.radius_m < a.radius_m
    if late.ok:
        assert t + late.fly_s + late.return_s + a.reserve_s <= spec.time_budget_s


def test_settings_that_leave_no_round_with_the_autopilots_return_are_refused(spec):
    """A budget that fits one round with the mission's return but not with PX4's is refused once
    PX4's return is known, naming the budget and how much longer that return is."""
    a = spec.adaptive
    px4 = ReturnModel.of(spec, vertical=PX4, disarm_s=7.2)
    ok = spec.time_budget_s
    while not adaptive_violations(dataclasses.replace(spec, time_budget_s=ok - 5.0), a):
        ok -= 5.0
    tight = dataclasses.replace(spec, time_budget_s=ok)
    assert adaptive_violations(tight, a) == []
    (key, text), *_ = adaptive_violations(tight, a, px4)
    assert key == "time_budget_s" and "the autopilot's return" in text and "s longer" in text


def test_the_rounds_pace_keeps_the_autopilots_cost_per_leg():
    """A survey of long legs flown 11 % slow fits about 1.11 x and no cost per leg; the rounds'
    short legs are planned with PX4's known 3 s a leg kept (``Pace.at_least``), so a 6-leg round
    planned at 40 s kinematic takes at least 40 x 1.11 + 18 s."""
    s = load_mission(ROOT / "missions" / "spiral.yaml")
    watch = BudgetWatch(plan_times(s), prior=PACE_PRIOR["PX4"])
    t = watch.plan.t_wp
    for k in range(1, 10):
        watch.update(t[0] + 1.11 * (t[k - 1] - t[0]), k)
    fitted = watch.pace_model()
    assert fitted.scale == pytest.approx(1.11, abs=0.01) and fitted.per_leg_s < 0.5
    pace = measured_pace(SimpleNamespace(budget=watch))
    assert pace == Pace(fitted.scale, 3.0, fitted.headwind)
    assert pace.legs(np.full(6, 40 / 6)) == pytest.approx(fitted.scale * 40 + 18)
    assert Pace(1.2, 0.0).at_least(None) == Pace(1.2, 0.0)
    assert measured_pace(SimpleNamespace()) is None
