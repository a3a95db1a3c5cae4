"""The PX4-like profile of the simulated vehicle: parameters over MAVLink, slower legs, the return
at ``MPC_XY_CRUISE``, and STATUSTEXT gated on ground-station heartbeats in simulated time as PX4
does."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sitl.protocol import Item
from sitl.vehicle import SimVehicle

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

from mission.flight.vehicle_process import free_udp_port  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
mav = mavutil.mavlink


def _items(vehicle, speed: float | None):
    o = vehicle.origin

    def wp(seq, cmd, e, n, z, params=(0.0, 0.0, 0.0, 0.0)):
        lat, lon, _ = o.to_geodetic(np.array([e, n, 0.0]))
        return Item(
            seq,
            3,
            cmd,
            int(seq == 0),
            1,
            params,
            int(round(float(lat) * 1e7)),
            int(round(float(lon) * 1e7)),
            z,
        )

    items = [wp(0, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 30.0)]
    if speed is not None:
        items.append(
            Item(1, 2, mav.MAV_CMD_DO_CHANGE_SPEED, 0, 1, (1.0, speed, -1.0, 0.0), 0, 0, 0.0)
        )
    items += [
        wp(len(items), mav.MAV_CMD_NAV_WAYPOINT, 200, 0, 30.0),
        wp(len(items) + 1, mav.MAV_CMD_NAV_WAYPOINT, 200, 200, 30.0),
    ]
    items.append(Item(len(items), 2, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 1, (0.0,) * 4, 0, 0, 0.0))
    return items


def _speeds(plan):
    """(horizontal leg speeds, vertical leg speeds, vertical leg heights) of a vehicle plan."""
    P = plan.profile.vertices
    d = np.diff(P, axis=0)
    vert = np.abs(d[:, 2]) > np.linalg.norm(d[:, :2], axis=1)
    return plan.profile.v_cruise[~vert], plan.profile.v_cruise[vert], d[vert, 2]


@pytest.mark.parametrize(
    "profile, factor, ret, up, down, land, low",
    [("default", 1.0, 5.0, 2.5, 2.5, 2.5, 0.0), ("px4", 0.93, 4.8, 1.5, 1.5, 0.7, 5.0)],
)
def test_profile_speeds_mission_and_return(profile, factor, ret, up, down, land, low):
    """Legs after a speed item fly at factor * that speed; the return at factor * MPC_XY_CRUISE
    (PX4: 4.8 m/s unless set; the default profile: the kinematics' cruise speed, so its flown time
    matches the plan); take-off at MPC_TKO_SPEED, the final descent at MPC_Z_V_AUTO_DN, then
    MPC_LAND_SPEED below MPC_LAND_ALT2."""
    v = SimVehicle(f"udpout:127.0.0.1:{free_udp_port()}", profile=profile)
    try:
        assert v.param("MPC_XY_CRUISE") == pytest.approx(ret)
        v.items = _items(v, 5.5)
        v.armed = True
        assert v.start_mission()
        horiz, vert, dz = _speeds(v.plan)
        # home->wp1, wp1->wp2, the return
        assert horiz == pytest.approx([5.5 * factor] * 2 + [ret * factor])
        expect = [(30.0, up)] + ([(-25.0, down), (-5.0, land)] if low else [(-30.0, down)])
        np.testing.assert_allclose(np.column_stack([dz, vert]), expect, atol=1e-6)
        assert v.plan.land_legs == (2 if low else 1)
        v.params["MPC_XY_CRUISE"] = 5.5  # what the runner sets
        v.start_mission(0)
        assert _speeds(v.plan)[0][-1] == pytest.approx(5.5 * factor)
        v.items = _items(v, None)  # no speed item: PX4 flies the legs at MPC_XY_CRUISE too
        v.start_mission(0)
        assert _speeds(v.plan)[0][0] == pytest.approx(5.5 * factor)
        assert v.texts["generated"] == 3 and v.text_queue[0][1] == "Executing Mission"
    finally:
        v.conn.close()


@pytest.mark.slow
def test_params_and_statustext_gate_over_mavlink(tmp_path):
    """PARAM_REQUEST_READ/PARAM_SET answered with REAL32 PARAM_VALUE; no STATUSTEXT without a
    ground-station heartbeat within 2.5 simulated s, queued texts older than 5 s dropped, every text
    logged (sent or not)."""
    port = free_udp_port()
    log = tmp_path / "texts.jsonl"
    v = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sitl.vehicle",
            "--port",
            str(port),
            "--speedup",
            "10",
            "--profile",
            "px4",
            "--statustext-log",
            str(log),
        ],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    gcs = mavutil.mavlink_connection(
        f"udpin:127.0.0.1:{port}", source_system=245, source_component=190
    )
    try:
        assert gcs.wait_heartbeat(timeout=10)
        gcs.mav.param_request_read_send(1, 1, b"MPC_XY_CRUISE", -1)
        pv = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=5)
        assert pv.param_id == "MPC_XY_CRUISE" and pv.param_value == pytest.approx(4.8)
        assert pv.param_type == mav.MAV_PARAM_TYPE_REAL32
        gcs.mav.param_set_send(1, 1, b"MPC_XY_CRUISE", 5.5, mav.MAV_PARAM_TYPE_REAL32)
        pv = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=5)
        assert pv.param_value == pytest.approx(5.5)

        def texts(wait: float) -> list[str]:
            end, out = time.monotonic() + wait, []
            while time.monotonic() < end:
                m = gcs.recv_match(type="STATUSTEXT", blocking=True, timeout=0.05)
                if m is not None:
                    out.append(m.text)
            return out

        gcs.mav.command_long_send(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        # no GCS heartbeat: 10 simulated s pass, the text is dropped after 5
        assert texts(1.0) == []
        gcs.mav.heartbeat_send(
            mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE
        )
        gcs.mav.command_long_send(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
        # within 2.5 simulated s of the heartbeat
        assert texts(0.15) == ["Disarmed by external command"]
        time.sleep(0.35)  # 3.5 simulated s: the gate is closed again
        gcs.mav.command_long_send(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        assert texts(0.2) == []
        gcs.mav.heartbeat_send(
            mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE
        )
        # queued < 5 s: sent once a heartbeat came
        assert texts(0.2) == ["Armed by external command"]
        rec = [json.loads(line) for line in log.read_text().splitlines()]
        assert [(r["text"], r["sent"]) for r in rec] == [
            ("Armed by external command", False),
            ("Disarmed by external command", True),
            ("Armed by external command", True),
        ]
    finally:
        gcs.close()
        v.terminate()
        v.wait(5)
