"""MAVLink handlers of the simulated vehicle: messages and commands in, acknowledgements out.

Commands: ARM_DISARM, DO_SET_MODE, MISSION_START, NAV_TAKEOFF, NAV_RETURN_TO_LAUNCH, NAV_LAND,
DO_PAUSE_CONTINUE, DO_CHANGE_SPEED, SET_MESSAGE_INTERVAL, REQUEST_MESSAGE,
REQUEST_AUTOPILOT_CAPABILITIES. A mixin of ``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

import math

from sitl.protocol import DEFAULT_INTERVALS, PHYSICS_DT, PX4_AUTO_MISSION, mav


class MavlinkHandlers:
    """Dispatch of received messages to the mission store, the mode machine and the stream
    scheduler."""

    def handle(self, msg) -> None:
        t = msg.get_type()
        if t == "COMMAND_LONG":
            self.on_command(
                msg.command,
                [
                    msg.param1,
                    msg.param2,
                    msg.param3,
                    msg.param4,
                    msg.param5,
                    msg.param6,
                    msg.param7,
                ],
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
        elif t == "HEARTBEAT":
            self.on_heartbeat_in(msg)
        elif t in ("PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "PARAM_SET"):
            self.on_param_message(msg)
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
                    self.say("Armed by external command")
                    self.send_heartbeat()  # the armed flag at once, not up to a wall second later
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
                    self.say("Disarmed by external command")
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
