"""Rounds planned on fresh data (issue 33 item 3): a lead fixed in vehicle seconds at every
speed-up, a wait (hold time) at a part's last waypoint sized by the measured estimate time within
the budget's spare seconds, and the built-in vehicle's hold honoured and ended by the next
upload."""

from __future__ import annotations

import asyncio
import dataclasses
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.adaptive import rounds
from mission.adaptive.planner import smallest_round_s, survey_spec
from mission.adaptive.rounds import (
    LATENCY_PRIOR_WALL_S,
    MAX_LEAD_SURVEY_SHARE,
    WAIT_ESTIMATES,
    AdaptiveRounds,
    lead_for,
    round_timing,
)
from mission.flight.estimates import LiveEstimates
from mission.spec import load_mission
from mission.trajectory.items import ACCEPTANCE_RADIUS_M, build_items
from sitl.protocol import Item
from sitl.vehicle import SimVehicle

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

from mission.flight.vehicle_process import free_udp_port  # noqa: E402

mav = mavutil.mavlink
ADAPTIVE = "missions/spiral_adaptive.yaml"


@pytest.fixture(scope="module")
def spec(repo_dir):
    return load_mission(repo_dir / ADAPTIVE)


# --------------------------------------------------------------------------- the lead and the wait


def test_the_lead_is_the_settings_at_every_speedup(spec):
    """The lead no longer grows with the speed-up (it was 8 wall s: 150 vehicle s at 20x): it is
    ``lead_s``, at most half the survey."""
    a = spec.adaptive
    assert lead_for(a) == pytest.approx(min(a.lead_s, MAX_LEAD_SURVEY_SHARE * a.survey_s))
    short = dataclasses.replace(a, survey_s=40.0)
    assert lead_for(short) == pytest.approx(20.0)


@pytest.mark.parametrize(
    "latency, speedup, spare, max_lead, lead, hold",
    [
        (1.0, 1.0, 200.0, 150.0, 30.0, 0.0),  # real time: the settings' lead, never a wait
        (12.0, 1.0, 200.0, 150.0, 30.0, 6.0),  # a very loaded machine at 1x: 36 s of estimates
        (None, 20.0, 200.0, 150.0, 30.0, 90.0),  # the prior (2 s) at 20x: 120 s, 90 waited
        (0.3, 20.0, 200.0, 150.0, 30.0, 0.0),  # measured: 18 s of estimates, within the lead
        (4.0, 20.0, 500.0, 150.0, 30.0, 210.0),  # slower: 240 s, within the spare budget
        (None, 20.0, 40.0, 150.0, 80.0, 40.0),  # the budget spares 40 s: the lead takes the rest
        (None, 15.0, 18.0, 50.0, 50.0, 18.0),  # ... up to half the survey
        (None, 20.0, -5.0, 150.0, 120.0, 0.0),  # no spare at all: the old way, a longer lead
    ],
)
def test_round_timing_table(latency, speedup, spare, max_lead, lead, hold):
    t = round_timing(latency, 0.0, speedup, 30.0, spare, max_lead)
    assert (t.lead_s, t.hold_s) == pytest.approx((lead, hold))


@settings(max_examples=300, deadline=None)
@given(
    latency=st.one_of(st.none(), st.floats(0.0, 30.0)),
    upload=st.floats(0.0, 5.0),
    speedup=st.floats(0.1, 50.0),
    lead=st.floats(0.0, 120.0),
    spare=st.floats(-50.0, 400.0),
    max_lead=st.floats(0.0, 400.0),
)
def test_round_timing_covers_the_plan_within_its_bounds(
    latency, upload, speedup, lead, spare, max_lead
):
    """The wait never exceeds what the budget spares, the lead is the settings' unless the wait
    cannot cover the plan's time, and lead plus wait cover it wherever the lead's cap allows."""
    t = round_timing(latency, upload, speedup, lead, spare, max_lead)
    lat = LATENCY_PRIOR_WALL_S if latency is None else latency
    need = (WAIT_ESTIMATES * lat + upload) * speedup
    assert 0.0 <= t.hold_s <= max(spare, 0.0) + 1e-9
    assert lead - 1e-9 <= t.lead_s <= max(max_lead, lead) + 1e-9
    if t.lead_s > lead + 1e-9:  # a longer lead only where the wait is all the budget spares
        assert t.hold_s == pytest.approx(max(spare, 0.0))
    if t.lead_s < max(max_lead, lead) - 1e-9:
        assert t.lead_s + t.hold_s >= need - 1e-6


def test_timing_grows_with_speedup():
    ts = [round_timing(None, 1.5, s, 30.0, 100.0, 150.0) for s in (1, 5, 10, 20, 40)]
    assert [t.hold_s for t in ts] == sorted(t.hold_s for t in ts)
    assert [t.lead_s for t in ts] == sorted(t.lead_s for t in ts)


def test_latency_is_the_longest_of_the_recent_estimates():
    lv = LiveEstimates()
    assert lv.latency_s() is None
    lv.wall_s = [9.0] + [0.2, 0.4, 0.3, 0.5, 0.6] * 2
    assert lv.latency_s() == pytest.approx(0.6)  # the slow warm-up estimate has aged out
    assert lv.latency_s(last=11) == pytest.approx(9.0)


class _Budget:
    def __init__(self, planned: float):
        self._p = planned

    def planned_s(self) -> float:
        return self._p


@pytest.mark.parametrize("speedup, planned, expect", [(1.0, 385.0, 0.0), (20.0, 385.0, 120.0)])
def test_the_survey_waits_only_what_the_budget_leaves(spec, speedup, planned, expect):
    ext = AdaptiveRounds(spec, spec.adaptive)
    ctx = dataclasses.make_dataclass("Ctx", ["speedup", "budget"])(speedup, _Budget(planned))
    assert ext.hold_s(ctx) == pytest.approx(expect)
    assert ext.timing.lead_s == pytest.approx(lead_for(spec.adaptive))
    # a survey that leaves 20 s after its plan, the reserve and the smallest round waits that
    end = survey_spec(spec, spec.adaptive.survey_s).waypoints_enu()[-1]
    least = smallest_round_s(spec, spec.adaptive, end)
    assert 10.0 < least < 60.0
    tight = spec.time_budget_s - spec.adaptive.reserve_s - least - 20.0
    ctx = dataclasses.make_dataclass("Ctx", ["speedup", "budget"])(20.0, _Budget(tight))
    assert ext.hold_s(ctx) == pytest.approx(20.0) and ext.survey_hold_s == pytest.approx(20.0)
    # the rest of round 1's planning time comes before the survey's end instead
    # ((3 estimates of the 2 s prior + a 1.5 s upload) x 20 = 150 s)
    assert ext.timing.lead_s == pytest.approx(min(150.0 - 20.0, 0.5 * spec.adaptive.survey_s))


# --------------------------------------------------------------------------- the items


def test_the_hold_is_on_the_last_waypoint_only(spec):
    plain = build_items(spec)
    held = build_items(spec, hold_s=42.0)
    wp = [i for i, it in enumerate(held) if it.command == mav.MAV_CMD_NAV_WAYPOINT]
    assert held[wp[-1]].params[0] == 42.0 and held[wp[-1]].params[1] == ACCEPTANCE_RADIUS_M
    assert all(held[i].params[0] == 0.0 for i in wp[:-1])

    # everything else as without a hold (a fixed mission's items are unchanged)
    def rest(items):  # repr: the NaN params compare equal
        return [repr(dataclasses.replace(it, params=(0.0, *it.params[1:]))) for it in items]

    assert rest(held) == rest(plain)
    assert all(it.params[0] == 0.0 for it in plain if it.command == mav.MAV_CMD_NAV_WAYPOINT)


# --------------------------------------------------------------------------- the built-in vehicle


def _mission_items(v: SimVehicle, hold: float) -> list[Item]:
    o = v.origin

    def wp(seq, cmd, e, n, z, p1=0.0):
        lat, lon, _ = o.to_geodetic(np.array([e, n, 0.0]))
        return Item(
            seq,
            3,
            cmd,
            int(seq == 0),
            1,
            (p1, 2.0, 0.0, 0.0),
            int(round(float(lat) * 1e7)),
            int(round(float(lon) * 1e7)),
            z,
        )

    return [
        wp(0, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 20.0),
        wp(1, mav.MAV_CMD_NAV_WAYPOINT, 50, 0, 20.0),
        wp(2, mav.MAV_CMD_NAV_WAYPOINT, 50, 50, 20.0, hold),
        Item(3, 2, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 1, (0.0,) * 4, 0, 0, 0.0),
    ]


def _run(v: SimVehicle, until: float, seen: list) -> None:
    """Advance the vehicle in 0.5 s steps, noting (time, current item, position)."""
    while v.sim_t < until:
        v.advance(v.sim_t + 0.5)
        seen.append((v.sim_t, v.current_seq, v.pos.copy()))


@pytest.mark.parametrize("hold", [0.0, 25.0])
def test_the_builtin_vehicle_waits_out_a_hold_time(hold):
    """At a waypoint with a hold time the vehicle stays, the item still current, for that long,
    then goes on (PX4 and ArduCopter report it reached after the wait); without one it goes on."""
    v = SimVehicle(f"udpout:127.0.0.1:{free_udp_port()}")
    try:
        v.items, v.armed = _mission_items(v, hold), True
        assert v.start_mission(0)
        seen: list = []
        _run(v, 200.0, seen)
        t = np.array([s[0] for s in seen])
        cur = np.array([s[1] for s in seen])
        pos = np.array([s[2] for s in seen])
        at_wp = np.linalg.norm(pos - (50.0, 50.0, 20.0), axis=1) < 0.5
        stay = t[at_wp & (cur == 2)]
        waited = stay.max() - stay.min() if len(stay) else 0.0
        assert waited == pytest.approx(hold, abs=1.0)
        assert cur[-1] >= 3 and pos[-1, 2] < 0.5  # returned and landed
    finally:
        v.conn.close()


def test_an_upload_ends_the_wait_at_once():
    """Setting the next item current during the hold (what a round's upload does) ends the wait
    there: the vehicle leaves within a step."""
    v = SimVehicle(f"udpout:127.0.0.1:{free_udp_port()}")
    try:
        v.items, v.armed = _mission_items(v, 60.0), True
        assert v.start_mission(0)
        seen: list = []
        while not (
            v.current_seq == 2 and np.linalg.norm(v.pos - (50.0, 50.0, 20.0)) < 0.5 and v.resume
        ):
            _run(v, v.sim_t + 0.5, seen)
            assert v.sim_t < 200.0
        t_arrive = v.sim_t
        _run(v, t_arrive + 5.0, seen)  # waiting
        assert v.current_seq == 2 and np.linalg.norm(v.pos - (50.0, 50.0, 20.0)) < 0.5
        v.current_seq = 3
        v.start_mission()  # MISSION_SET_CURRENT in mission mode
        assert v.resume is None
        _run(v, v.sim_t + 3.0, seen)
        assert np.linalg.norm(v.pos[:2] - (50.0, 50.0)) > 1.0 or v.pos[2] > 20.5  # on its way
    finally:
        v.conn.close()


# --------------------------------------------------------------------------- the wait, said


class _Ctx:
    """What ``_estimate_saying_the_wait`` reads of a flight: its events."""

    def __init__(self):
        self.events: list[str] = []

    def event(self, kind: str, text: str, warn: bool = False) -> None:
        self.events.append(text)


def _slow_estimate(seconds: float, started: list):
    async def estimate(ctx):
        started.append(1)
        await asyncio.sleep(seconds)
        return {"x_m": 1.0}

    return estimate


@pytest.mark.parametrize("waiting, hold, said", [(True, 40.0, 1), (False, 40.0, 0), (True, 0.0, 0)])
def test_a_wait_for_the_plan_is_said_once(monkeypatch, waiting, hold, said):
    """While the round's estimate runs, a vehicle waiting at its part's end (with a hold) gets one
    line naming the part, the round and the longest wait; the estimate comes back unchanged."""
    started: list = []
    monkeypatch.setattr(rounds.estimates, "estimate", _slow_estimate(0.3, started))
    monkeypatch.setattr(rounds, "waiting_at_end", lambda ctx, wps, off: waiting)
    ctx = _Ctx()
    d = asyncio.run(rounds._estimate_saying_the_wait(ctx, np.zeros((3, 3)), 2, hold, 1))
    assert d == {"x_m": 1.0} and started == [1]
    lines = [e for e in ctx.events if e.startswith("waiting at")]
    assert len(lines) == said
    if said:
        assert lines[0] == "waiting at the end of round 1 for round 2 (at most 40 s)"


def test_the_estimate_is_cancelled_with_the_flight(monkeypatch):
    """A flight that ends (its coroutine cancelled) while the round's estimate runs leaves no
    estimate task behind."""
    started: list = []
    monkeypatch.setattr(rounds.estimates, "estimate", _slow_estimate(30.0, started))
    monkeypatch.setattr(rounds, "waiting_at_end", lambda ctx, wps, off: False)

    async def main():
        t = asyncio.ensure_future(
            rounds._estimate_saying_the_wait(_Ctx(), np.zeros((3, 3)), 2, 0, 0)
        )
        await asyncio.sleep(0.2)
        t.cancel()
        with pytest.raises(asyncio.CancelledError):
            await t
        await asyncio.sleep(0)
        others = [x for x in asyncio.all_tasks() if x is not asyncio.current_task()]
        assert all(x.done() for x in others)

    asyncio.run(main())
    assert started == [1]
