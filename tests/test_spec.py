"""Mission YAML: every shipped mission loads and is flyable; bad fields name the key and the
file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mission.errors import InputError
from mission.spec import load_mission
from mission.trajectory.checks import assert_flyable

MISSIONS = Path(__file__).resolve().parents[1] / "missions"


@pytest.mark.parametrize("path", sorted(MISSIONS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_missions_load_and_are_flyable(path):
    spec = load_mission(path)
    rep = assert_flyable(spec)
    assert rep.duration_s <= spec.time_budget_s
    fp = spec.flight_path_enu()
    assert fp[0, 2] == 0.0 and fp[-1, 2] == 0.0  # starts and ends on the ground
    assert np.allclose(fp[0], spec.home_enu)
    tx = spec.resolve_tx(np.random.default_rng(1))
    assert tx.shape == (3,) and spec.field.rover_area.contains(tx[:2])


def test_default_mission_values():
    spec = load_mission()
    assert spec.name == "spiral" and spec.altitude_m == 30.0 and spec.time_budget_s == 600.0
    assert spec.return_behaviour == "rtl" and spec.vehicle.connection is None
    # the AFAR launch point (300.21, 54.14) m is 0.44 m inside the east edge: moved 4 m inside
    # (checks.RETURN_OVERSHOOT_M + home_margin_m + 1 m), straight west
    assert spec.home_enu == pytest.approx([296.65, 54.14, 0.0], abs=0.05)
    assert (
        spec.sim_config().dt_s == 0.03
        and spec.kinematics().cruise_speed_mps == spec.cruise_speed_mps
    )


def test_explicit_waypoints_and_geodetic_points():
    spec = load_mission(MISSIONS / "waypoints.yaml")
    w = spec.waypoints_enu()
    assert w.shape == (8, 3)
    assert w[0].tolist() == [250.0, 100.0, 30.0] and w[-1, 2] == 40.0
    lat, lon, _ = spec.field.origin.to_geodetic([w[6, 0], w[6, 1], 0.0])
    assert (float(lat), float(lon)) == pytest.approx((35.72840, -78.69700), abs=1e-9)
    assert spec.source.tx == (17.67, 194.29, 1.5)


def test_land_behaviour_ends_below_last_waypoint(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text("return_behaviour: land\ntrajectory: {waypoints: [[50, 150], [100, 150]]}\n")
    fp = load_mission(p).flight_path_enu()
    assert fp[-1].tolist() == [100.0, 150.0, 0.0]


def test_custom_field(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text("""
field:
  preset: custom
  origin: {lat_deg: 35.0, lon_deg: -78.0, alt_m: 100}
  flight_area: {lat_min: 35.0, lat_max: 35.002, lon_min: -78.0, lon_max: -77.997}
  rover_area: {polygon: [[35.001, -78.0], [35.001, -77.997], [35.003, -77.997], [35.003, -78.0]]}
home: [10, 10]
trajectory: {generator: lawnmower, params: {spacing_m: 30}}
""")
    spec = load_mission(p)
    assert spec.field.origin.alt_m == 100.0
    w = spec.waypoints_enu()
    assert np.all(spec.field.flight_area.contains(w, 5.0 - 1e-6))
    assert np.all(w[:, 1] > 100)  # the overlap is the northern half


BAD = [
    ("altitude_m: thirty\n", "altitude_m", "expected a number"),
    ("cruise_speed_mps: -3\n", "cruise_speed_mps", "must be >"),
    ("trajectory: {generator: zigzag}\n", "trajectory.generator", "zigzag"),
    (
        "trajectory: {generator: spiral, params: {spacing_m: -5}}\n",
        "trajectory.params.spacing_m",
        "must be > 0",
    ),
    (
        "trajectory: {generator: spiral, params: {spacing: 5}}\n",
        "trajectory.params.spacing",
        "unknown",
    ),
    ("trajectory: {waypoints: [[1, 2], [3]]}\n", "trajectory.waypoints[1]", "expected [x, y]"),
    ("source: {tx: somewhere}\n", "source.tx", "random"),
    ("source: {seed: 1.5}\n", "source.seed", "integer"),
    ("return_behaviour: hover\n", "return_behaviour", "rtl"),
    ("altitude_limits_m: [100, 10]\n", "altitude_limits_m", "min < max"),
    ("vehicle: {kinematics: {accel_mps2: 0}}\n", "vehicle.kinematics.accel_mps2", "must be >"),
    ("field: {flight_area: {lat_min: 35.0}}\n", "field.flight_area.lat_max", "missing"),
    ("altitud_m: 30\n", "altitud_m", "unknown key"),
    ("- just a list\n", None, "expected a mapping"),
]


@pytest.mark.parametrize("text,key,what", BAD, ids=[b[1] or "not-a-mapping" for b in BAD])
def test_bad_fields_name_key_and_file(tmp_path, text, key, what):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(InputError) as ei:
        load_mission(p)
    msg = str(ei.value)
    assert str(p) in msg and what in msg
    if key:
        assert ei.value.field == key and f"'{key}'" in msg


def test_missing_file_and_malformed_yaml(tmp_path):
    with pytest.raises(InputError, match="not found") as ei:
        load_mission(tmp_path / "nope.yaml")
    assert "nope.yaml" in str(ei.value)
    p = tmp_path / "broken.yaml"
    p.write_text("trajectory: {generator: spiral\naltitude_m: [30\n")
    with pytest.raises(InputError, match="malformed YAML at line") as ei:
        load_mission(p)
    assert "broken.yaml" in str(ei.value)
