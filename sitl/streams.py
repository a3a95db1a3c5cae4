"""Telemetry out of the simulated vehicle: status messages on the wall clock, streams on simulated
time.

Rates set by SET_MESSAGE_INTERVAL count in simulated time (as PX4/ArduPilot SITL do); status streams
(GPS_RAW_INT, EXTENDED_SYS_STATE, ...) repeat at most ``STATUS_WALL_HZ`` times per wall-clock
second, so the cost per wall second stays bounded at high speed-up.  A mixin of
``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

import math

from mission.flight.context import BUILTIN_PRODUCT
from sitl.protocol import (
    FAST_STREAMS,
    PX4_AUTO_MISSION,
    PX4_MAIN_AUTO,
    SENSORS,
    STATUS_WALL_HZ,
    mav,
)


class StreamScheduler:
    """Senders of every message the vehicle emits, and the schedule of the periodic ones."""

    def send_heartbeat(self) -> None:
        base = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.main_mode == PX4_MAIN_AUTO:
            base |= mav.MAV_MODE_FLAG_AUTO_ENABLED | mav.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.armed:
            base |= mav.MAV_MODE_FLAG_SAFETY_ARMED
        custom = (self.main_mode << 16) | (self.sub_mode << 24)
        status = mav.MAV_STATE_ACTIVE if self.armed else mav.MAV_STATE_STANDBY
        self.mav.heartbeat_send(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_PX4, base, custom, status)

    def send_sys_status(self) -> None:
        self.mav.sys_status_send(SENSORS, SENSORS, SENSORS, 250, 16000, 500, 80, 0, 0, 0, 0, 0, 0)

    def send_home(self) -> None:
        o = self.origin
        self.mav.home_position_send(
            int(round(o.lat_deg * 1e7)),
            int(round(o.lon_deg * 1e7)),
            int(round(o.alt_m * 1000)),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            self.t_ms * 1000,
        )

    def send_mission_current(self) -> None:
        total = len(self.items)
        state = (
            mav.MISSION_STATE_NO_MISSION
            if total == 0
            else mav.MISSION_STATE_ACTIVE
            if self.sub_mode == PX4_AUTO_MISSION and self.armed
            else mav.MISSION_STATE_NOT_STARTED
        )
        self.mav.mission_current_send(min(self.current_seq, max(total - 1, 0)), total, state, 0)

    def send_by_id(self, msgid: int) -> bool:
        if msgid == mav.MAVLINK_MSG_ID_HOME_POSITION:
            self.send_home()
        elif msgid == mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            caps = (
                mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mav.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
            )
            self.mav.autopilot_version_send(
                caps,
                (1 << 24) | (15 << 16),
                0,
                0,
                0,
                [0] * 8,
                [0] * 8,
                [0] * 8,
                *BUILTIN_PRODUCT,
                1,
            )
        elif msgid == mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            self.mav.extended_sys_state_send(mav.MAV_VTOL_STATE_UNDEFINED, self.landed_state)
            self._ess_sent = self.landed_state
        elif msgid == mav.MAVLINK_MSG_ID_MISSION_CURRENT:
            self.send_mission_current()
        elif msgid == mav.MAVLINK_MSG_ID_SYS_STATUS:
            self.send_sys_status()
        else:
            return False
        return True

    def send_stream(self, msgid: int, lat: float, lon: float) -> None:
        ms = self.t_ms
        if msgid == mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            v = self.v_s
            hdg = int(round(math.degrees(self.yaw) * 100)) % 36000
            self.mav.global_position_int_send(
                ms,
                int(round(lat * 1e7)),
                int(round(lon * 1e7)),
                int(round((self.origin.alt_m + self.pos[2]) * 1000)),
                int(round(self.pos[2] * 1000)),
                int(v[1] * 100),
                int(v[0] * 100),
                int(-v[2] * 100),
                hdg,
            )
        elif msgid == mav.MAVLINK_MSG_ID_ATTITUDE:
            yaw = math.atan2(math.sin(self.yaw), math.cos(self.yaw))
            self.mav.attitude_send(ms, self.roll, self.pitch, yaw, 0.0, 0.0, 0.0)
        elif msgid == mav.MAVLINK_MSG_ID_GPS_RAW_INT:
            sp = math.hypot(self.v_s[0], self.v_s[1])
            self.mav.gps_raw_int_send(
                ms * 1000,
                3,
                int(round(lat * 1e7)),
                int(round(lon * 1e7)),
                int(round((self.origin.alt_m + self.pos[2]) * 1000)),
                80,
                120,
                int(sp * 100),
                65535,
                14,
            )
        else:
            self.send_by_id(msgid)

    def _interval(self, msgid: int, iv: float) -> float:
        """Effective interval (sim s) of a stream: status streams at most ``STATUS_WALL_HZ`` per
        wall second."""
        return iv if msgid in FAST_STREAMS else max(iv, self.speedup / STATUS_WALL_HZ)

    def _send_due(self, la: float, lo: float) -> float:
        """Send the streams due at the current simulated time; returns the next due time."""
        nxt = math.inf
        for msgid, iv in self.intervals.items():
            due = self.next_due.get(msgid, 0.0)
            if self.sim_t + 1e-9 >= due:
                self.send_stream(msgid, la, lo)
                iv = self._interval(msgid, iv)
                due = self.next_due[msgid] = max(due + iv, self.sim_t + iv * 0.5)
            nxt = min(nxt, due)
        return nxt

    def wall_tasks(self, now: float) -> None:
        """Messages sent on the wall clock (link liveness), and mission-upload retries."""
        w = self._wall_next
        if now >= w["hb"]:
            self.send_heartbeat()
            w["hb"] = now + 1.0
        if now >= w["sys"]:
            self.send_sys_status()
            w["sys"] = now + 1.0
        if now >= w["cur"]:
            self.send_mission_current()
            w["cur"] = now + 1.0
        self.retry_upload(now)
