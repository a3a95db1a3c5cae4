"""The mission phase per row has two producers that must agree where both apply: a planned path's
geometry (``simulate.leg_phases``, what ``rfsl simulate`` logs; the adaptive simulator's legs by
construction) and a flown vehicle's events (``flight.phases.PhaseTracker``); one set of names
(``flightlog.PHASES``) and one item rule."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mission.adaptive.simflight import fixed_path
from mission.flight.phases import PhaseTracker, final_phase
from mission.flightlog import GROUND, LAND, MISSION, PHASES, RETURN, TAKEOFF
from mission.simulate import leg_phases
from mission.spec import load_mission

MISSIONS = sorted((Path(__file__).resolve().parents[1] / "missions").glob("*.yaml"))


def _runs(phase, item) -> list[tuple[str, int]]:
    """Consecutive distinct (phase, item) pairs."""
    out: list[tuple[str, int]] = []
    for p, i in zip(phase, item, strict=True):
        if not out or out[-1] != (str(p), int(i)):
            out.append((str(p), int(i)))
    return out


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.stem)
def test_planned_path_geometry_agrees_with_the_simulators_construction(path):
    spec = load_mission(path)
    legs, names = fixed_path(spec)
    assert list(leg_phases(legs)[0]) == names
    phase, item = leg_phases(spec.flight_path_enu())
    n = len(spec.waypoints_enu())
    tail = [(RETURN, -1), (LAND, -1)] if spec.return_behaviour == "rtl" else [(LAND, -1)]
    assert _runs(phase, item) == [(TAKEOFF, -1), *[(MISSION, k) for k in range(n)], *tail]
    assert set(phase) <= set(PHASES)


@pytest.mark.parametrize("behaviour", ["rtl", "land"])
def test_flown_events_give_the_planned_paths_phases_and_items(behaviour):
    """A vehicle flying the mission as uploaded (take-off, speed, waypoints, final item) logs,
    through ``PhaseTracker``, the same phase/item sequence the simulator derives from the planned
    path."""
    spec = dataclasses.replace(load_mission(), return_behaviour=behaviour)
    n = len(spec.waypoints_enu())
    first_wp, last_item = 2, n + 2  # items: take-off, change speed, n waypoints, RTL or LAND
    tr = PhaseTracker()
    tr.configure(first_wp, last_item, final_phase(behaviour))
    events = [
        lambda t: tr.on_landed_state(t, "TAKING_OFF"),
        lambda t: tr.on_landed_state(t, "IN_AIR"),
    ]
    events += [lambda t, k=k: tr.on_progress(t, first_wp + k) for k in range(n)]
    if behaviour == "rtl":
        events.append(lambda t: tr.on_progress(t, last_item))
    events += [
        lambda t: tr.on_landed_state(t, "LANDING"),
        lambda t: tr.on_landed_state(t, "ON_GROUND"),
    ]
    for t, e in enumerate(events):
        e(float(t))
    flown = _runs(*tr.at(np.arange(len(events), dtype=float)))
    assert flown[-1] == (GROUND, -1)
    planned = _runs(*leg_phases(spec.flight_path_enu()))
    assert flown[:-1] == planned
    assert final_phase("land") == LAND and final_phase("rtl") == RETURN
