"""The simulated vehicle speaks the MAVLink protocols a ground station uses (pymavlink as the
GCS)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

from mission.flight.runner import free_udp_port  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
mav = mavutil.mavlink


def test_heartbeat_upload_download_and_streams():
    port = free_udp_port()
    v = subprocess.Popen(
        [sys.executable, "-m", "sitl.vehicle", "--port", str(port), "--speedup", "10"],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    try:
        hb = gcs.wait_heartbeat(timeout=10)
        assert hb.type == mav.MAV_TYPE_QUADROTOR and hb.autopilot == mav.MAV_AUTOPILOT_PX4
        # upload 2 items
        gcs.mav.mission_count_send(1, 1, 2, 0)
        for seq in range(2):
            req = gcs.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_REQUEST"], blocking=True, timeout=5
            )
            assert req is not None and req.seq == seq
            gcs.mav.mission_item_int_send(
                1,
                1,
                seq,
                3,
                16 if seq else 22,
                int(seq == 0),
                1,
                0,
                0,
                0,
                0,
                357274400 + seq * 1000,
                -786960700,
                30.0,
                0,
            )
        ack = gcs.recv_match(type="MISSION_ACK", blocking=True, timeout=5)
        assert ack.type == mav.MAV_MISSION_ACCEPTED
        # download
        gcs.mav.mission_request_list_send(1, 1, 0)
        cnt = gcs.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
        assert cnt.count == 2
        gcs.mav.mission_request_int_send(1, 1, 1, 0)
        it = gcs.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=5)
        assert it.seq == 1 and it.x == 357275400
        # message interval in simulated time: 40 Hz of vehicle time
        gcs.mav.command_long_send(
            1,
            1,
            mav.MAV_CMD_SET_MESSAGE_INTERVAL,
            0,
            mav.MAVLINK_MSG_ID_ATTITUDE,
            25000,
            0,
            0,
            0,
            0,
            0,
        )
        ack = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
        assert ack.result == mav.MAV_RESULT_ACCEPTED
        ts = []
        while len(ts) < 60:
            m = gcs.recv_match(type="ATTITUDE", blocking=True, timeout=5)
            ts.append(m.time_boot_ms)
        dt = (ts[-1] - ts[20]) / (len(ts) - 21)
        assert 20 <= dt <= 30
        # home on request, clear
        gcs.mav.command_long_send(
            1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, mav.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0
        )
        assert gcs.recv_match(type="HOME_POSITION", blocking=True, timeout=5) is not None
        gcs.mav.mission_clear_all_send(1, 1, 0)
        gcs.mav.mission_request_list_send(1, 1, 0)
        assert gcs.recv_match(type="MISSION_COUNT", blocking=True, timeout=5).count == 0
    finally:
        gcs.close()
        v.terminate()
        v.wait(5)
