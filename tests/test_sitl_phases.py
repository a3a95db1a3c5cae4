"""Mission phase per log row (``phase``, ``mission_item``): written as text/int columns, read back,
and derived from the flight path in simulated logs."""

from __future__ import annotations

import numpy as np

from mission.flightlog import PHASES, make_meta, read_flight_log, write_flight_log
from mission.geo import Origin
from mission.physics import make_model
from mission.simulate import simulate_flight
from mission.spec import load_mission

O = Origin(35.727, -78.698, 90.0)


def test_text_phase_column_round_trips(tmp_path):
    n = 6
    cols = {
        "t_s": np.arange(n) * 0.1,
        "lat_deg": np.full(n, O.lat_deg),
        "lon_deg": np.full(n, O.lon_deg),
        "alt_m": np.full(n, 120.0),
        "rel_alt_m": np.full(n, 30.0),
        "rss_dbm": np.full(n, -60.0),
        "phase": np.array(["ground", "takeoff", "mission", "mission", "return", "land"]),
        "mission_item": np.array([-1, -1, 0, 1, -1, -1]),
    }
    p = write_flight_log(tmp_path / "f.csv", cols, make_meta(O, {"kind": "sim"}))
    header, first = p.read_text().splitlines()[:2]
    assert header.endswith(",rss_dbm,phase,mission_item")
    assert first.endswith(",ground,-1")
    log = read_flight_log(p)
    assert log.columns["phase"].tolist() == cols["phase"].tolist()
    assert log.columns["mission_item"].tolist() == [-1, -1, 0, 1, -1, -1]


def test_simulated_log_has_phases_in_flight_order(tmp_path):
    spec = load_mission("missions/spiral.yaml")
    f = simulate_flight(
        spec.flight_path_enu(),
        np.array([10.0, 10.0, 1.5]),
        make_model("free-space"),
        spec.sim_config(),
        np.random.default_rng(1),
    )
    cols = f.log_columns(spec.field.origin)
    phase, item = cols["phase"], cols["mission_item"]
    order = [PHASES.index(p) for p in phase]
    assert np.all(np.diff(order) >= 0), "phases must follow take-off -> mission -> return -> land"
    assert set(phase) == {"takeoff", "mission", "return", "land"}
    assert np.all((item >= 0) == (phase == "mission"))
    mission = phase == "mission"
    assert item[mission].min() == 0 and item[mission].max() == len(spec.waypoints_enu()) - 1
    assert np.all(np.diff(item[mission]) >= 0)
    # cruise height throughout the mission and the return; on the ground at the ends
    assert np.all(np.abs(f.enu_m[mission | (phase == "return"), 2] - 30.0) < 0.5)
    assert f.enu_m[0, 2] < 0.1 and f.enu_m[-1, 2] < 0.1
    p = write_flight_log(tmp_path / "sim.csv", cols, make_meta(spec.field.origin, {"kind": "sim"}))
    log = read_flight_log(p)
    assert log.columns["phase"].tolist() == phase.tolist()
