"""The embedded vehicle flies with the mission's full kinematics, so its flight time matches the
budget check.

The vehicle is spawned exactly as ``fly-mission`` does (``runner.spawn_vehicle`` with the mission's
``Kinematics`` as JSON), a pymavlink ground station uploads the mission's raw items, arms and starts
it, and the take-off-to-landing time on the vehicle's clock is compared with
``check_mission(spec).duration_s``. Also: the speed-up notice and the automatic telemetry rate.
"""

from __future__ import annotations

import dataclasses
import json
import os

import pytest
import yaml
import yaml as _yaml

from mission.spec import load_mission
from mission.trajectory.checks import check_mission
from mission.trajectory.items import build_items
from mission.trajectory.kinematics import Kinematics
from sitl.vehicle import build_parser, parse_kinematics, run_from_args  # noqa: F401

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

from mission.flight.runner import (  # noqa: E402
    auto_rate_hz,
    free_udp_port,
    spawn_vehicle,
    wall_clock_notice,
)
from mission.flight.vehicle_process import stop_vehicle  # noqa: E402

mav = mavutil.mavlink

NON_DEFAULT = {
    "accel_mps2": 3.0,
    "climb_rate_mps": 4.0,
    "corner_exponent": 0.5,
    "yaw_rate_dps": 120.0,
    "response_s": 0.5,
}


def _mission(tmp_path, kin: dict | None):
    d = {
        "name": "kin",
        "altitude_m": 20,
        "cruise_speed_mps": 9.0,
        "time_budget_s": 600,
        "return_behaviour": "rtl",
        "trajectory": {"waypoints": [[80, 80], [200, 80], [200, 200], [80, 200]]},
        "vehicle": {"speedup": 1.0, **({"kinematics": kin} if kin else {})},
    }
    f = tmp_path / "kin.yaml"
    f.write_text(yaml.safe_dump(d))
    return load_mission(f)


def _fly_vehicle(spec, speedup: float) -> float:
    """Fly ``spec``'s raw mission on a spawned vehicle; returns take-off-to-landed seconds (vehicle
    clock)."""
    port = free_udp_port()
    o = spec.field.origin
    lat, lon, alt = o.to_geodetic(spec.home_enu)
    proc = spawn_vehicle(port, speedup, (float(lat), float(lon), float(alt)), spec.kinematics(), 0)
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    try:
        assert gcs.wait_heartbeat(timeout=10)
        items = build_items(spec, (float(lat), float(lon), float(alt)))
        gcs.mav.mission_count_send(1, 1, len(items), 0)
        while True:
            m = gcs.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=5
            )
            assert m is not None
            if m.get_type() == "MISSION_ACK":
                assert m.type == mav.MAV_MISSION_ACCEPTED
                break
            it = items[m.seq]
            gcs.mav.mission_item_int_send(
                1,
                1,
                m.seq,
                it.frame,
                it.command,
                int(m.seq == 0),
                1,
                *it.params,
                it.x,
                it.y,
                it.z,
                0,
            )
        gcs.mav.command_long_send(  # 50 Hz positions: the time of the landed-state changes to 20 ms
            1,
            1,
            mav.MAV_CMD_SET_MESSAGE_INTERVAL,
            0,
            mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
            20000,
            0,
            0,
            0,
            0,
            0,
        )
        gcs.mav.command_long_send(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        gcs.mav.command_long_send(1, 1, mav.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
        t_up = t_down = t_last = None
        while t_down is None:
            m = gcs.recv_match(
                type=["EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT"], blocking=True, timeout=10
            )
            assert m is not None, "vehicle went silent"
            if m.get_type() == "GLOBAL_POSITION_INT":
                t_last = m.time_boot_ms / 1000.0
            elif t_last is None:
                continue
            elif m.landed_state != mav.MAV_LANDED_STATE_ON_GROUND and t_up is None:
                t_up = t_last
            elif m.landed_state == mav.MAV_LANDED_STATE_ON_GROUND and t_up is not None:
                t_down = t_last
        return t_down - t_up
    finally:
        gcs.close()
        stop_vehicle(proc)  # it ignores the terminal's signals: the flight stops it so


@pytest.mark.parametrize("kin", [NON_DEFAULT, None], ids=["non-default", "default"])
def test_vehicle_flight_time_matches_budget_check(tmp_path, kin):
    spec = _mission(tmp_path, kin)
    planned = check_mission(spec).duration_s
    flown = _fly_vehicle(spec, speedup=100)
    # take-off/landing detection: allow 0.5 s plus 3 %
    assert abs(flown - planned) <= 0.03 * planned + 0.5, (flown, planned)


def _leg_time_from_rest_to_rest(length_m: float, speed: float, accel: float) -> float:
    """Closed form: accelerate at ``accel`` to ``speed`` (or as far as half the leg allows), cruise,
    brake."""
    if length_m >= speed**2 / accel:
        return length_m / speed + speed / accel
    return 2.0 * (length_m / accel) ** 0.5


@pytest.mark.parametrize("kin", [NON_DEFAULT, None], ids=["non-default", "default"])
def test_vehicle_flight_time_matches_closed_form(tmp_path, kin):
    """Independent reference: an out-and-back mission from above home stops at every vertex (climb,
    120 m out, reversal, 120 m back, descent), so its flight time is a sum of rest-to-rest legs in
    closed form."""
    d = {
        "name": "outback",
        "altitude_m": 20,
        "cruise_speed_mps": 9.0,
        "time_budget_s": 600,
        "return_behaviour": "rtl",
        "home": [80, 80],
        "trajectory": {"waypoints": [[80, 80], [200, 80], [80, 80]]},
        "vehicle": {"speedup": 1.0, **({"kinematics": kin} if kin else {})},
    }
    f = tmp_path / "outback.yaml"
    f.write_text(_yaml.safe_dump(d))
    spec = load_mission(f)
    k = Kinematics(**(kin or {}))
    reference = 2 * _leg_time_from_rest_to_rest(
        20.0, k.climb_rate_mps, k.accel_mps2
    ) + 2 * _leg_time_from_rest_to_rest(120.0, 9.0, k.accel_mps2)
    flown = _fly_vehicle(spec, speedup=100)
    assert abs(flown - reference) <= 0.03 * reference + 0.5, (flown, reference)


def test_non_default_kinematics_change_the_flight_time(tmp_path):
    """Guard for the test above: the overrides matter (else it would pass with cruise speed
    alone)."""
    a = check_mission(_mission(tmp_path, NON_DEFAULT)).duration_s
    b = check_mission(_mission(tmp_path, None)).duration_s
    assert abs(a - b) > 0.1 * b


def test_kinematics_round_trip_through_the_command_line():
    kin = Kinematics(cruise_speed_mps=7.0, **NON_DEFAULT)

    assert parse_kinematics(json.dumps(dataclasses.asdict(kin))) == kin
    assert parse_kinematics(None) == Kinematics()
    with pytest.raises(ValueError):
        parse_kinematics('{"warp_speed": 9}')
    args = build_parser().parse_args(
        ["--kinematics", json.dumps({"accel_mps2": 2.0}), "--cruise-speed", "6"]
    )
    assert args.cruise_speed == 6.0 and json.loads(args.kinematics) == {"accel_mps2": 2.0}


def test_wall_clock_notice_and_auto_rate():
    slow = wall_clock_notice(540.0, 1.0)
    assert "9.0 min of wall-clock time" in slow and "--speedup 20" in slow
    fast = wall_clock_notice(540.0, 20.0)
    assert "27 s of wall-clock time" in fast and "--speedup" not in fast
    assert auto_rate_hz(1.0) == 50.0 and auto_rate_hz(20.0) == 30.0 and auto_rate_hz(100.0) == 30.0
    assert auto_rate_hz(15.0) == 40.0
