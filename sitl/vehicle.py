"""A simulated PX4-like MAVLink multicopter: mission protocol, commands, telemetry on a simulated clock.

Why: ``fly-mission`` must be testable end to end (and usable for demos and training) without a real
autopilot, and it must exercise the same MAVLink paths as PX4 so that the runner is not written against a
toy.  The vehicle speaks MAVLink 2 over UDP and *sends* to the ground station's port, exactly like PX4 SITL
does: the ground station listens (MAVSDK ``udpin://0.0.0.0:14540``, QGroundControl on 14550) and the
vehicle answers whoever talks back to it.

Flight model: the project's kinematics (``mission.trajectory.kinematics.plan_profile``) over the path
implied by the uploaded mission from the current position (take-off climb, waypoints, return to launch,
landing), re-planned on every mode change; attitude follows incrementally from the motion (yaw along the
track with a rate limit, roll/pitch from the smoothed acceleration plus drag against a gusty wind), the same
physics as ``attitude_from_motion``.  The physics step is 10 ms of simulated time up to speed-up 10 and
coarser above (at most 50 ms, never coarser than the fastest requested position/attitude stream), and the
status streams (GPS_RAW_INT, EXTENDED_SYS_STATE, ...) repeat at most 10 times per wall-clock second (the
landed state also at once on a change), so the cost per wall-clock second stays bounded at high speed-up.
The full ``Kinematics`` comes as JSON (``--kinematics``; ``fly-mission`` passes the mission's).
Simulated time runs ``--speedup`` times faster than the wall clock and is the ``time_boot_ms`` of every
message, so rates requested with SET_MESSAGE_INTERVAL are honoured in simulated time (as PX4/ArduPilot SITL
do).

Run: ``python -m sitl.vehicle --port 14540 --speedup 5`` or ``rfsl sitl``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import select
import sys
import time
from dataclasses import dataclass, field

os.environ.setdefault("MAVLINK20", "1")

import numpy as np  # noqa: E402
from pymavlink import mavutil  # noqa: E402

from mission.geo import Origin  # noqa: E402
from mission.trajectory.kinematics import FlightProfile, G, Kinematics, plan_profile  # noqa: E402

mav = mavutil.mavlink

# PX4 custom modes (px4_custom_mode.h): main mode in bits 16-23, sub mode in bits 24-31.
PX4_MAIN_POSCTL, PX4_MAIN_AUTO = 3, 4
PX4_AUTO_READY, PX4_AUTO_TAKEOFF, PX4_AUTO_LOITER, PX4_AUTO_MISSION, PX4_AUTO_RTL, PX4_AUTO_LAND = (
    1,
    2,
    3,
    4,
    5,
    6,
)

DEFAULT_HOME = (35.72744, -78.69607, 0.0)  # AFAR field (Lake Wheeler), ground altitude 0 (relative use)
PHYSICS_DT = 0.01  # s of simulated time per physics step (100 Hz) up to speed-up 10
MAX_PHYSICS_DT = 0.05  # coarsest step at high speed-up (the attitude response is 0.8 s, turbulence 0.6 s)
WIND_TAU_S, TURB_TAU_S, TURB_DEG = 6.0, 0.6, 0.8  # gust and turbulence correlation times; turbulence sd
# streams sent exactly at their requested rate in vehicle time; the others (status: GPS_RAW_INT,
# EXTENDED_SYS_STATE, ...) repeat the same content and are sent at most STATUS_WALL_HZ times per wall-clock
# second at high speed-up (the landed state is also sent at once whenever it changes)
STATUS_WALL_HZ = 10.0
SENSORS = (
    mav.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mav.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mav.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mav.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mav.MAV_SYS_STATUS_SENSOR_GPS
    | mav.MAV_SYS_STATUS_PREARM_CHECK
)
# default stream intervals (s of simulated time), like PX4's "normal" link profile
FAST_STREAMS = frozenset({mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mav.MAVLINK_MSG_ID_ATTITUDE})
DEFAULT_INTERVALS = {
    mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.2,
    mav.MAVLINK_MSG_ID_ATTITUDE: 0.05,
    mav.MAVLINK_MSG_ID_GPS_RAW_INT: 0.2,
    mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 0.2,
}


class LocalGeodetic:
    """ENU about an origin -> WGS84 lat/lon (deg), vectorised and cheap (no per-call overhead of pymap3d).

    ENU -> ECEF is a rotation and a shift; ECEF -> geodetic uses Bowring's closed form, which agrees with
    the iterative solution to well under a millimetre near the ground, so positions agree with
    ``Origin.to_geodetic`` (pymap3d) to ~1e-10 deg.
    """

    A, F = 6378137.0, 1.0 / 298.257223563  # WGS84

    def __init__(self, origin: Origin) -> None:
        a, f = self.A, self.F
        self.b = a * (1.0 - f)
        self.e2 = f * (2.0 - f)
        self.ep2 = self.e2 / (1.0 - self.e2)
        p0, l0 = math.radians(origin.lat_deg), math.radians(origin.lon_deg)
        sp, cp, sl, cl = math.sin(p0), math.cos(p0), math.sin(l0), math.cos(l0)
        n = a / math.sqrt(1.0 - self.e2 * sp * sp)
        h = origin.alt_m
        self.x0 = np.array([(n + h) * cp * cl, (n + h) * cp * sl, (n * (1.0 - self.e2) + h) * sp])
        self.R = np.array([[-sl, -sp * cl, cp * cl], [cl, -sp * sl, cp * sl], [0.0, cp, sp]])

    def latlon(self, enu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(enu, dtype=float).reshape(-1, 3) @ self.R.T + self.x0
        a, b = self.A, self.b
        p = np.hypot(x[:, 0], x[:, 1])
        th = np.arctan2(x[:, 2] * a, p * b)
        lat = np.arctan2(
            x[:, 2] + self.ep2 * b * np.sin(th) ** 3, p - self.e2 * a * np.cos(th) ** 3
        )
        return np.degrees(lat), np.degrees(np.arctan2(x[:, 1], x[:, 0]))


@dataclass
class Item:
    """One stored mission item (MISSION_ITEM_INT fields)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    params: tuple[float, float, float, float]
    x: int
    y: int
    z: float


@dataclass
class Plan:
    """A timed flight the vehicle is executing: profile from ``t0`` (sim s), item reach times, end action."""

    profile: FlightProfile
    t0: float
    reach: list[tuple[float, int]] = field(default_factory=list)  # (time since t0, item seq), ascending
    land_at_end: bool = False
    from_ground: bool = False
    n_legs: int = 0


class SimVehicle:
    """State and protocol handling of one simulated multicopter (one MAVLink system, component 1)."""

    def __init__(
        self,
        url: str,
        home: tuple[float, float, float] = DEFAULT_HOME,
        speedup: float = 1.0,
        seed: int = 0,
        kin: Kinematics | None = None,
        gust_mps: float = 1.5,
        sysid: int = 1,
        verbose: bool = False,
    ) -> None:
        self.conn = mavutil.mavlink_connection(
            url, source_system=sysid, source_component=1, dialect="common", autoreconnect=True
        )
        self.mav = self.conn.mav
        self.origin = Origin(*home)
        self.geo = LocalGeodetic(self.origin)
        self.speedup = float(speedup)
        self.kin = kin or Kinematics()
        self.cruise = self.kin.cruise_speed_mps
        self.verbose = verbose
        self.noise = np.random.default_rng(seed)  # wind gusts and turbulence
        self.gust_sigma = gust_mps
        # state
        self.sim_t = 0.0
        self.pos = np.zeros(3)
        self.armed = False
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_LOITER
        self.plan: Plan | None = None
        self.items: list[Item] = []
        self.current_seq = 0
        self.landed_state = mav.MAV_LANDED_STATE_ON_GROUND
        self.disarm_at: float | None = None
        self.takeoff_alt = 2.5
        # attitude filter state
        self.v_s = [0.0, 0.0, 0.0]  # smoothed velocity, ENU
        self.a_s = [0.0, 0.0, 0.0]  # smoothed acceleration, ENU
        self.prev_pos = [0.0, 0.0, 0.0]
        self.yaw = 0.0
        self.roll = self.pitch = 0.0
        self.wind = [0.0, 0.0]
        self.turb = [0.0, 0.0]
        # streams
        self.intervals = dict(DEFAULT_INTERVALS)
        self.next_due = dict.fromkeys(self.intervals, 0.0)
        self._rx: dict | None = None  # mission upload in progress
        self._wall_next = {"hb": 0.0, "sys": 0.0, "cur": 0.0}
        self.uploads = 0
        self._ess_sent = -1  # landed state last sent in EXTENDED_SYS_STATE

    # ------------------------------------------------------------------ helpers
    def log(self, msg: str) -> None:
        if self.verbose:
            print(f"[sitl t={self.sim_t:8.2f}] {msg}", file=sys.stderr, flush=True)

    @property
    def t_ms(self) -> int:
        return int(round(self.sim_t * 1000))

    @property
    def flying(self) -> bool:
        return self.landed_state != mav.MAV_LANDED_STATE_ON_GROUND

    def _item_enu(self, it: Item, last: np.ndarray) -> np.ndarray:
        """ENU of a mission item (lat/lon 0 means 'here'); z relative to home unless the frame is global."""
        if it.frame in (
            mav.MAV_FRAME_GLOBAL_INT,
            mav.MAV_FRAME_GLOBAL,
            mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
            mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mav.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
        ):
            if it.x == 0 and it.y == 0:
                xy = last[:2]
            else:
                xy = self.origin.to_enu(it.x * 1e-7, it.y * 1e-7, self.origin.alt_m)[:2]
            z = (
                it.z - self.origin.alt_m
                if it.frame in (mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_INT)
                else it.z
            )
            return np.array([xy[0], xy[1], z])
        return np.array([last[0], last[1], it.z])

    def _start_plan(
        self,
        pts: list[np.ndarray],
        seq_at_vertex: list[tuple[int, int]],
        land: bool,
        speeds: list[float] | None = None,
    ) -> None:
        """Plan and start flying the polyline ``pts`` from the current position (already ``pts[0]``)."""
        P = np.asarray(pts, dtype=float)
        if len(P) < 2:  # nothing to fly: hover here, every item reached at once
            prof = plan_profile(P[:1], self.kin)
            reach = [(0.0, s) for _, s in seq_at_vertex]
        else:
            legs = np.diff(P, axis=0)
            L = np.linalg.norm(legs, axis=1)
            if speeds is None:
                speeds = [self.cruise] * len(L)
            vert = np.abs(legs[:, 2]) / np.maximum(L, 1e-9) > 0.7
            sp = np.where(vert, self.kin.climb_rate_mps, np.asarray(speeds, dtype=float))
            prof = plan_profile(P, self.kin, speeds=sp)
            reach = [(float(prof.t_vertex[min(v, len(prof.t_vertex) - 1)]), s) for v, s in seq_at_vertex]
        self.plan = Plan(
            prof, self.sim_t, sorted(reach), land, from_ground=not self.flying, n_legs=len(P) - 1
        )
        if not self.flying and prof.duration_s > 0:
            self.landed_state = mav.MAV_LANDED_STATE_TAKEOFF
        self.log(f"plan: {len(P)} vertices, {prof.duration_s:.1f} s, land={land}")

    @staticmethod
    def _append(pts: list[np.ndarray], p: np.ndarray) -> int:
        if np.linalg.norm(p - pts[-1]) > 1e-3:
            pts.append(np.asarray(p, dtype=float))
        return len(pts) - 1

    # ------------------------------------------------------------------ flight modes
    def start_mission(self, from_seq: int | None = None) -> bool:
        """Fly the stored mission from ``from_seq`` (default: the current item)."""
        if not self.armed or not self.items:
            return False
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_MISSION
        if from_seq is not None:
            self.current_seq = from_seq
        if self.current_seq >= len(self.items):
            self.current_seq = 0
        pts = [self.pos.copy()]
        marks: list[tuple[int, int]] = []
        speeds: list[float] = []
        speed = self.cruise
        land = False
        for it in self.items[self.current_seq :]:
            n0 = len(pts)
            if it.command == mav.MAV_CMD_NAV_TAKEOFF:
                tgt = self._item_enu(it, pts[-1])
                self._append(pts, np.array([pts[-1][0], pts[-1][1], tgt[2]]))
                self._append(pts, tgt)
            elif it.command in (
                mav.MAV_CMD_NAV_WAYPOINT,
                mav.MAV_CMD_NAV_LOITER_TIME,
                mav.MAV_CMD_NAV_LOITER_UNLIM,
            ):
                if (
                    it.seq == 0
                    and it.frame == mav.MAV_FRAME_GLOBAL
                    and it.command == mav.MAV_CMD_NAV_WAYPOINT
                ):
                    marks.append((len(pts) - 1, it.seq))  # ArduPilot-style home item: not flown
                    continue
                self._append(pts, self._item_enu(it, pts[-1]))
            elif it.command == mav.MAV_CMD_DO_CHANGE_SPEED and it.params[1] > 0:
                speed = float(it.params[1])
            elif it.command == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
                z = max(pts[-1][2], 5.0)
                self._append(pts, np.array([pts[-1][0], pts[-1][1], z]))
                self._append(pts, np.array([0.0, 0.0, z]))
                self._append(pts, np.zeros(3))
                land = True
            elif it.command == mav.MAV_CMD_NAV_LAND:
                p = self._item_enu(it, pts[-1])
                self._append(pts, np.array([p[0], p[1], pts[-1][2]]))
                self._append(pts, np.array([p[0], p[1], 0.0]))
                land = True
            speeds.extend([speed] * (len(pts) - n0))
            marks.append((len(pts) - 1, it.seq))
            if land:
                break
        self._start_plan(pts, marks, land, speeds)
        return True

    def hold(self) -> None:
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_LOITER
        if self.flying:
            self._start_plan([self.pos.copy()], [], False)
        else:
            self.plan = None

    def rtl(self) -> bool:
        if not self.armed:
            return False
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_RTL
        if not self.flying:
            self.plan = None
            return True
        pts = [self.pos.copy()]
        z = max(self.pos[2], 5.0)
        self._append(pts, np.array([self.pos[0], self.pos[1], z]))
        self._append(pts, np.array([0.0, 0.0, z]))
        self._append(pts, np.zeros(3))
        self._start_plan(pts, [], True)
        return True

    def land(self) -> bool:
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_LAND
        if not self.flying:
            return True
        self._start_plan([self.pos.copy(), np.array([self.pos[0], self.pos[1], 0.0])], [], True)
        return True

    def takeoff(self, alt: float | None = None) -> bool:
        if not self.armed:
            return False
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_TAKEOFF
        z = alt if alt and alt > 0 else self.takeoff_alt
        self._start_plan([self.pos.copy(), np.array([self.pos[0], self.pos[1], z])], [], False)
        return True

    def set_mode(self, main: int, sub: int) -> bool:
        if main == PX4_MAIN_AUTO and sub == PX4_AUTO_MISSION:
            if self.armed:
                return self.start_mission()
            self.main_mode, self.sub_mode = main, sub
            return bool(self.items)
        if main == PX4_MAIN_AUTO and sub == PX4_AUTO_RTL:
            return self.rtl()
        if main == PX4_MAIN_AUTO and sub == PX4_AUTO_LAND:
            return self.land()
        if main == PX4_MAIN_AUTO and sub == PX4_AUTO_TAKEOFF:
            return self.takeoff()
        self.main_mode, self.sub_mode = main, sub
        self.hold()
        self.main_mode, self.sub_mode = main, sub
        return True

    # ------------------------------------------------------------------ MAVLink in
    def handle(self, msg) -> None:
        t = msg.get_type()
        if t == "COMMAND_LONG":
            self.on_command(
                msg.command,
                [msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7],
                msg.get_srcSystem(),
                msg.get_srcComponent(),
            )
        elif t == "COMMAND_INT":
            self.on_command(
                msg.command,
                [msg.param1, msg.param2, msg.param3, msg.param4, msg.x * 1e-7, msg.y * 1e-7, msg.z],
                msg.get_srcSystem(),
                msg.get_srcComponent(),
            )
        elif t == "MISSION_COUNT":
            self.on_mission_count(msg)
        elif t in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self.on_mission_item(msg)
        elif t == "MISSION_REQUEST_LIST":
            mt = getattr(msg, "mission_type", 0)
            n = len(self.items) if mt == 0 else 0
            self.mav.mission_count_send(msg.get_srcSystem(), msg.get_srcComponent(), n, mt)
        elif t in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self.on_mission_request(msg)
        elif t == "MISSION_CLEAR_ALL":
            mt = getattr(msg, "mission_type", 0)
            if mt in (0, 255):
                self.items, self.current_seq = [], 0
            self.mav.mission_ack_send(
                msg.get_srcSystem(), msg.get_srcComponent(), mav.MAV_MISSION_ACCEPTED, mt
            )
        elif t == "MISSION_SET_CURRENT":
            if 0 <= msg.seq < len(self.items):
                self.current_seq = msg.seq
                if self.sub_mode == PX4_AUTO_MISSION and self.armed:
                    self.start_mission()
            self.send_mission_current()
        elif t == "SET_MODE":
            self.set_mode((msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF)

    def ack(self, cmd: int, result: int, sysid: int, compid: int) -> None:
        self.mav.command_ack_send(cmd, result, 0, 0, sysid, compid)

    def on_command(self, cmd: int, p: list[float], sysid: int, compid: int) -> None:
        ok, fail, unsup = mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED, mav.MAV_RESULT_UNSUPPORTED
        res = unsup
        if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] >= 0.5:
                res = ok if not self.armed or True else ok
                if not self.armed:
                    self.armed, self.disarm_at = True, None
                    self.log("armed")
                    self.send_home()
            else:
                if self.flying and int(p[1]) != 21196:
                    res = fail
                else:
                    self.armed, self.plan = False, None
                    self.landed_state = mav.MAV_LANDED_STATE_ON_GROUND
                    self.pos[2] = 0.0
                    res = ok
                    self.log("disarmed")
        elif cmd == mav.MAV_CMD_DO_SET_MODE:
            res = ok if self.set_mode(int(p[1]), int(p[2])) else fail
        elif cmd == mav.MAV_CMD_MISSION_START:
            res = ok if self.start_mission(int(p[0]) if p[0] > 0 else None) else fail
        elif cmd == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            res = ok if self.rtl() else fail
        elif cmd == mav.MAV_CMD_NAV_LAND:
            res = ok if self.land() else fail
        elif cmd == mav.MAV_CMD_NAV_TAKEOFF:
            alt = p[6] - self.origin.alt_m if math.isfinite(p[6]) else None
            res = ok if self.takeoff(alt) else fail
        elif cmd == mav.MAV_CMD_DO_PAUSE_CONTINUE:
            if p[0] < 0.5:
                self.hold()
                res = ok
            else:
                res = ok if self.start_mission() else fail
        elif cmd == mav.MAV_CMD_DO_CHANGE_SPEED:
            if p[1] > 0:
                self.cruise = float(p[1])
            res = ok
        elif cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
            msgid, us = int(p[0]), p[1]
            if us < 0:
                self.intervals.pop(msgid, None)
            elif us == 0:
                if msgid in DEFAULT_INTERVALS:
                    self.intervals[msgid] = DEFAULT_INTERVALS[msgid]
            else:
                self.intervals[msgid] = max(us * 1e-6, PHYSICS_DT)
            self.next_due[msgid] = self.sim_t
            res = ok
        elif cmd == mav.MAV_CMD_REQUEST_MESSAGE:
            res = ok if self.send_by_id(int(p[0])) else unsup
        elif cmd == mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            res = ok if self.send_by_id(mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION) else unsup
        self.ack(cmd, res, sysid, compid)

    def on_mission_count(self, msg) -> None:
        mt = getattr(msg, "mission_type", 0)
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.count == 0:
            if mt == 0:
                self.items, self.current_seq = [], 0
            self.mav.mission_ack_send(*src, mav.MAV_MISSION_ACCEPTED, mt)
            return
        self._rx = {
            "type": mt,
            "count": msg.count,
            "items": [],
            "src": src,
            "asked": time.monotonic(),
            "tries": 0,
        }
        self.mav.mission_request_int_send(*src, 0, mt)

    def on_mission_item(self, msg) -> None:
        rx = self._rx
        if rx is None or getattr(msg, "mission_type", 0) != rx["type"]:
            return
        if msg.seq != len(rx["items"]):
            self.mav.mission_request_int_send(*rx["src"], len(rx["items"]), rx["type"])
            return
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":  # float lat/lon
            x, y = int(round(msg.x * 1e7)), int(round(msg.y * 1e7))
        rx["items"].append(
            Item(
                msg.seq,
                msg.frame,
                msg.command,
                msg.current,
                msg.autocontinue,
                (msg.param1, msg.param2, msg.param3, msg.param4),
                x,
                y,
                msg.z,
            )
        )
        if len(rx["items"]) < rx["count"]:
            rx["asked"], rx["tries"] = time.monotonic(), 0
            self.mav.mission_request_int_send(*rx["src"], len(rx["items"]), rx["type"])
            return
        self._rx = None
        if rx["type"] == 0:
            self.items = rx["items"]
            cur = [i.seq for i in self.items if i.current]
            self.current_seq = cur[0] if cur else 0
            self.uploads += 1
            self.log(f"mission uploaded: {len(self.items)} items")
        self.mav.mission_ack_send(*rx["src"], mav.MAV_MISSION_ACCEPTED, rx["type"])
        self.send_mission_current()

    def on_mission_request(self, msg) -> None:
        mt = getattr(msg, "mission_type", 0)
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if mt != 0 or not 0 <= msg.seq < len(self.items):
            self.mav.mission_ack_send(*src, mav.MAV_MISSION_INVALID_SEQUENCE, mt)
            return
        it = self.items[msg.seq]
        self.mav.mission_item_int_send(
            *src,
            it.seq,
            it.frame,
            it.command,
            int(it.seq == self.current_seq),
            it.autocontinue,
            *it.params,
            it.x,
            it.y,
            it.z,
            0,
        )

    # ------------------------------------------------------------------ MAVLink out
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
                caps, (1 << 24) | (15 << 16), 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 1
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

    # ------------------------------------------------------------------ physics
    def _events(self) -> None:
        """Item reached, take-off/landing transitions and auto-disarm at the current simulated time."""
        pl = self.plan
        if pl is not None:
            tau = self.sim_t - pl.t0
            while pl.reach and pl.reach[0][0] <= tau:
                _, seq = pl.reach.pop(0)
                self.mav.mission_item_reached_send(seq)
                self.current_seq = seq + 1 if seq + 1 < len(self.items) else seq
                self.send_mission_current()
            done = tau >= pl.profile.duration_s
            if self.flying:
                if self.landed_state == mav.MAV_LANDED_STATE_TAKEOFF and (self.pos[2] > 1.0 or done):
                    self.landed_state = mav.MAV_LANDED_STATE_IN_AIR
                if pl.land_at_end:
                    i = int(np.searchsorted(pl.profile.t_vertex, tau, side="right")) - 1
                    if i >= pl.n_legs - 1 and self.pos[2] < pl.profile.vertices[-2][2] - 0.1:
                        self.landed_state = mav.MAV_LANDED_STATE_LANDING
            if done:
                if pl.land_at_end:
                    self.pos[2] = 0.0
                    self.landed_state = mav.MAV_LANDED_STATE_ON_GROUND
                    self.disarm_at = self.sim_t + 1.0
                    self.log("landed")
                self.plan = None
                if self.flying:
                    self.pos = pl.profile.vertices[-1].copy()
        if self.disarm_at is not None and self.sim_t >= self.disarm_at:
            self.disarm_at = None
            if self.armed and not self.flying:
                self.armed = False
                if self.sub_mode == PX4_AUTO_MISSION:
                    self.current_seq = len(self.items)  # mission finished
                self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_LOITER
                self.log("auto-disarmed")
                self.send_heartbeat()

    def physics_dt(self) -> float:
        """Simulated seconds per physics step: 10 ms up to speed-up 10, coarser above (a multiple of 10 ms,
        at most ``MAX_PHYSICS_DT`` and never coarser than the fastest requested position/attitude stream),
        so that the cost per wall-clock second stays bounded while the requested rates hold in vehicle time."""
        dt = min(PHYSICS_DT * max(self.speedup / 10.0, 1.0), MAX_PHYSICS_DT)
        fastest = min((iv for m, iv in self.intervals.items() if m in FAST_STREAMS), default=dt)
        return PHYSICS_DT * max(1, math.floor(min(dt, fastest) / PHYSICS_DT + 1e-6))

    def _interval(self, msgid: int, iv: float) -> float:
        """Effective interval (sim s) of a stream: status streams at most ``STATUS_WALL_HZ`` per wall second."""
        return iv if msgid in FAST_STREAMS else max(iv, self.speedup / STATUS_WALL_HZ)

    def _next_event_time(self) -> float:
        """The simulated time at which ``_events`` must next run (item reached, plan end, landing, disarm)."""
        t = self.disarm_at if self.disarm_at is not None else math.inf
        pl = self.plan
        if pl is None:
            return t
        if self.landed_state == mav.MAV_LANDED_STATE_TAKEOFF:
            return self.sim_t  # watch the climb through 1 m at every step
        t = min(t, pl.t0 + pl.profile.duration_s)
        if pl.reach:
            t = min(t, pl.t0 + pl.reach[0][0])
        if pl.land_at_end and self.flying and self.landed_state != mav.MAV_LANDED_STATE_LANDING:
            tv = pl.profile.t_vertex
            t = min(t, pl.t0 + float(tv[min(max(pl.n_legs - 1, 0), len(tv) - 1)]))
        return t

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

    def advance(self, target_t: float) -> None:
        """Step the simulation up to simulated time ``target_t``, emitting the due telemetry.

        The positions of the whole chunk come vectorised from the plan; the incremental attitude model
        (velocity/acceleration smoothing, Ornstein-Uhlenbeck wind gusts and turbulence, rate-limited yaw,
        roll/pitch from acceleration plus drag, the same physics as ``attitude_from_motion``) runs on plain
        floats, and the event logic runs only at the times where something can happen."""
        dt = self.physics_dt()
        n = int((target_t - self.sim_t) / dt + 1e-9)
        if n <= 0:
            return
        times_a = self.sim_t + dt * np.arange(1, n + 1)
        plan0 = self.plan
        if plan0 is not None:
            P = plan0.profile.position(np.clip(times_a - plan0.t0, 0.0, None))
        else:
            P = np.repeat(self.pos[None, :], n, axis=0)
        lat_a, lon_a = self.geo.latlon(P)
        lat, lon = lat_a.tolist(), lon_a.tolist()
        times, Pl = times_a.tolist(), P.tolist()
        noise = self.noise.standard_normal((n, 4)).tolist()
        k = self.kin
        alpha = dt / (k.response_s + dt)
        aw, at = math.exp(-dt / WIND_TAU_S), math.exp(-dt / TURB_TAU_S)
        sw = self.gust_sigma * math.sqrt(1.0 - aw * aw)
        st = math.radians(TURB_DEG) * math.sqrt(1.0 - at * at)
        yaw_lim = math.radians(k.yaw_rate_dps) * dt
        k_drag = math.tan(math.radians(k.drag_pitch_deg_per_mps)) * G
        tilt = math.radians(k.max_tilt_deg)
        vx, vy, vz = self.v_s
        ax, ay, az = self.a_s
        ppx, ppy, ppz = self.prev_pos
        we, wn = self.wind
        tp, tr = self.turb
        yaw, roll, pitch = self.yaw, self.roll, self.pitch
        flying = self.flying
        next_ev = self._next_event_time()
        next_st = min((self.next_due.get(m, 0.0) for m in self.intervals), default=math.inf)
        two_pi, pi = 2.0 * math.pi, math.pi
        for i in range(n):
            t = self.sim_t = times[i]
            if self.plan is plan0:
                self.pos = P[i]
                px, py, pz = Pl[i]
                la, lo = lat[i], lon[i]
            else:  # the plan ended inside this chunk: hold the last position
                px, py, pz = (float(c) for c in self.pos)
                la = lo = None
            # smoothed velocity and acceleration
            nvx = vx + ((px - ppx) / dt - vx) * alpha
            nvy = vy + ((py - ppy) / dt - vy) * alpha
            nvz = vz + ((pz - ppz) / dt - vz) * alpha
            ax += ((nvx - vx) / dt - ax) * alpha
            ay += ((nvy - vy) / dt - ay) * alpha
            az += ((nvz - vz) / dt - az) * alpha
            vx, vy, vz = nvx, nvy, nvz
            ppx, ppy, ppz = px, py, pz
            # wind gusts and turbulence: Ornstein-Uhlenbeck processes (exact discretisation)
            g = noise[i]
            we = aw * we + sw * g[0]
            wn = aw * wn + sw * g[1]
            tp = at * tp + st * g[2]
            tr = at * tr + st * g[3]
            if flying:
                if vx * vx + vy * vy > 0.09:
                    d = (math.atan2(vx, vy) - yaw + pi) % two_pi - pi
                    yaw = (yaw + max(-yaw_lim, min(yaw_lim, d))) % two_pi
                ae = ax + k_drag * (vx - we)
                an = ay + k_drag * (vy - wn)
                cy, sy = math.cos(yaw), math.sin(yaw)
                pitch = max(-tilt, min(tilt, -math.atan2(an * cy + ae * sy, G) + tp))
                roll = max(-tilt, min(tilt, math.atan2(-an * sy + ae * cy, G) + tr))
            else:
                roll = pitch = 0.0
            if t + 1e-9 >= next_ev:
                self._events()
                flying = self.flying
                next_ev = self._next_event_time()
                if self.landed_state != self._ess_sent:
                    self.send_by_id(mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)  # landed state: at once
            if t + 1e-9 >= next_st:
                self.v_s = [vx, vy, vz]
                self.yaw, self.roll, self.pitch = yaw, roll, pitch
                if la is None:
                    la, lo = (float(c[0]) for c in self.geo.latlon(self.pos))
                next_st = self._send_due(la, lo)
        self.v_s, self.a_s, self.prev_pos = [vx, vy, vz], [ax, ay, az], [ppx, ppy, ppz]
        self.wind, self.turb = [we, wn], [tp, tr]
        self.yaw, self.roll, self.pitch = yaw, roll, pitch

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
        rx = self._rx
        if rx is not None and now - rx["asked"] > 0.5:
            rx["tries"] += 1
            if rx["tries"] > 5:
                self.mav.mission_ack_send(*rx["src"], mav.MAV_MISSION_OPERATION_CANCELLED, rx["type"])
                self._rx = None
            else:
                rx["asked"] = now
                self.mav.mission_request_int_send(*rx["src"], len(rx["items"]), rx["type"])

    def run(self, duration_s: float | None = None, parent_pid: int | None = None) -> None:
        """Main loop: read MAVLink, advance simulated time with the wall clock times ``speedup``.

        With ``parent_pid`` the loop ends once that process is gone (checked every wall-clock second), so
        a vehicle started by ``fly-mission`` never outlives it, even after a ``kill -9``."""
        wall0 = time.monotonic()
        fd = self.conn.port.fileno()
        next_parent_check = wall0
        while True:
            now = time.monotonic()
            if duration_s is not None and now - wall0 > duration_s:
                return
            if parent_pid is not None and now >= next_parent_check:
                next_parent_check = now + 1.0
                if os.getppid() != parent_pid:
                    self.log("parent process gone: exiting")
                    return
            self.wall_tasks(now)
            self.advance((now - wall0) * self.speedup)
            r, _, _ = select.select([fd], [], [], 0.004)
            if r:
                while True:
                    try:
                        msg = self.conn.recv_match(blocking=False)
                    except (ConnectionError, OSError):
                        msg = None
                    if msg is None:
                        break
                    if msg.get_type() != "BAD_DATA":
                        self.handle(msg)


def parse_home(text: str) -> tuple[float, float, float]:
    """``LAT,LON[,ALT]`` -> a tuple (the altitude is the ground AMSL, default 0)."""
    parts = [float(p) for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise ValueError(f"--home wants LAT,LON[,ALT], got {text!r}")
    return (parts[0], parts[1], parts[2] if len(parts) == 3 else 0.0)


def parse_kinematics(text: str | None) -> Kinematics:
    """``--kinematics`` JSON (an object of ``Kinematics`` fields) -> ``Kinematics``; None -> defaults."""
    if not text:
        return Kinematics()
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"--kinematics is not valid JSON: {e}") from None
    names = {f.name for f in dataclasses.fields(Kinematics)}
    if not isinstance(d, dict) or set(d) - names:
        raise ValueError(f"--kinematics wants a JSON object with keys among {sorted(names)}, got {text!r}")
    return Kinematics(**{k: None if v is None else float(v) for k, v in d.items()})


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m sitl.vehicle", description=__doc__.splitlines()[0])
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``python -m sitl.vehicle`` and ``rfsl sitl``."""
    p.add_argument(
        "--port",
        type=int,
        default=14540,
        help="ground-station UDP port the vehicle sends to (PX4 SITL: 14540; QGroundControl: 14550)",
    )
    p.add_argument("--host", default="127.0.0.1", help="ground-station host (default 127.0.0.1)")
    p.add_argument(
        "--url", default=None, help="full pymavlink URL instead of --host/--port (e.g. tcpin:0.0.0.0:5760)"
    )
    p.add_argument("--speedup", type=float, default=1.0, help="simulated seconds per wall-clock second")
    p.add_argument("--home", default=None, help="LAT,LON[,ALT] of the take-off point (default: AFAR field)")
    p.add_argument(
        "--kinematics",
        default=None,
        help="JSON object of Kinematics fields (cruise_speed_mps, accel_mps2, climb_rate_mps, "
        "corner_exponent, yaw_rate_dps, ...); fly-mission passes the mission's full kinematics here",
    )
    p.add_argument(
        "--cruise-speed",
        type=float,
        default=None,
        help="default cruise speed, m/s (overrides the one in --kinematics; default 5)",
    )
    p.add_argument("--gust", type=float, default=1.5, help="wind gust standard deviation, m/s")
    p.add_argument("--seed", type=int, default=0, help="seed of the wind and turbulence")
    p.add_argument("--duration", type=float, default=None, help="stop after this many wall-clock seconds")
    p.add_argument("--parent-pid", type=int, default=None, help="exit when this parent process is gone")
    p.add_argument("-v", "--verbose", action="store_true", help="print state changes to stderr")


def run_from_args(args: argparse.Namespace) -> int:
    """Build the vehicle from parsed options and run it until killed."""
    if args.speedup <= 0:
        raise ValueError("--speedup must be positive")
    home = parse_home(args.home) if args.home else DEFAULT_HOME
    url = args.url or f"udpout:{args.host}:{args.port}"
    kin = parse_kinematics(args.kinematics)
    if args.cruise_speed is not None:
        kin = dataclasses.replace(kin, cruise_speed_mps=float(args.cruise_speed))
    v = SimVehicle(url, home, args.speedup, args.seed, kin, gust_mps=args.gust, verbose=args.verbose)
    print(
        f"sitl: simulated PX4 quadrotor, MAVLink 2 on {url}, home {home[0]:.6f},{home[1]:.6f}, "
        f"speed-up {args.speedup:g}",
        file=sys.stderr,
        flush=True,
    )
    try:
        v.run(args.duration, args.parent_pid)
    except KeyboardInterrupt:
        pass
    return 0


def main(argv: list[str] | None = None) -> int:
    return run_from_args(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
