"""The mode machine of the simulated vehicle: mission, hold, return to launch, land, take-off (PX4
modes).

Every mode change plans the path it implies from the current position with the project's kinematics
(``plan_profile``), starting from rest, so the flown time matches the mission's time-budget check.
A mixin of ``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mission.trajectory.kinematics import FlightProfile, plan_profile
from sitl.protocol import (
    PX4_AUTO_LAND,
    PX4_AUTO_LOITER,
    PX4_AUTO_MISSION,
    PX4_AUTO_RTL,
    PX4_AUTO_TAKEOFF,
    PX4_MAIN_AUTO,
    Item,
    mav,
)


@dataclass
class Plan:
    """A timed flight the vehicle is executing: profile from ``t0`` (sim s), item reach times, end
    action."""

    profile: FlightProfile
    t0: float
    # (time since t0, item seq), ascending
    reach: list[tuple[float, int]] = field(default_factory=list)
    land_at_end: bool = False
    from_ground: bool = False
    n_legs: int = 0
    land_legs: int = 1  # legs of the final descent (2 when it slows down near the ground)
    # (item seq, seconds): the plan ends at a waypoint with a hold time (param1), waits, goes on
    hold: tuple[int, float] | None = None


class ModeMachine:
    """Mode changes and the plans they start (``self.plan``)."""

    def _item_enu(self, it: Item, last: np.ndarray) -> np.ndarray:
        """ENU of a mission item (lat/lon 0 means 'here'); z relative to home unless the frame is
        global."""
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
        """Plan and start flying the polyline ``pts`` from the current position (already
        ``pts[0]``)."""
        P = np.asarray(pts, dtype=float)
        self.resume = None  # a new plan ends any hold in progress
        land_legs = 1
        low = self.param("MPC_LAND_ALT2")
        if (
            land
            and len(P) >= 2
            and 0 < low < P[-2, 2] - P[-1, 2]
            and np.allclose(P[-2, :2], P[-1, :2])
        ):
            # the final descent slows below ``low``
            P = np.vstack([P[:-1], P[-1] + [0.0, 0.0, low], P[-1:]])
            seq_at_vertex = [(v + (v == len(P) - 2), s) for v, s in seq_at_vertex]
            land_legs = 2
        if len(P) < 2:  # nothing to fly: hover here, every item reached at once
            prof = plan_profile(P[:1], self.kin)
            reach = [(0.0, s) for _, s in seq_at_vertex]
        else:
            legs = np.diff(P, axis=0)
            L = np.linalg.norm(legs, axis=1)
            if speeds is None:  # a return or a commanded leg: PX4 flies those at MPC_XY_CRUISE
                speeds = [self.param("MPC_XY_CRUISE")] * len(L)
            speeds = list(speeds) + [speeds[-1]] * (len(L) - len(speeds))  # the vertex added above
            vert = np.abs(legs[:, 2]) / np.maximum(L, 1e-9) > 0.7
            # a profile that flies slower
            horiz = np.asarray(speeds, dtype=float) * self.profile.speed_factor
            vs = np.where(
                legs[:, 2] > 0, self.param("MPC_TKO_SPEED"), self.param("MPC_Z_V_AUTO_DN")
            )
            if land and vert[-1] and legs[-1, 2] < 0 and (land_legs == 2 or low >= -legs[-1, 2]):
                vs[-1] = self.param("MPC_LAND_SPEED")
            sp = np.where(vert, vs, horiz)
            prof = plan_profile(P, self.kin, speeds=sp)
            reach = [
                (float(prof.t_vertex[min(v, len(prof.t_vertex) - 1)]), s) for v, s in seq_at_vertex
            ]
        self.plan = Plan(
            prof,
            self.sim_t,
            sorted(reach),
            land,
            from_ground=not self.flying,
            n_legs=len(P) - 1,
            land_legs=land_legs,
        )
        if not self.flying and prof.duration_s > 0:
            self.landed_state = mav.MAV_LANDED_STATE_TAKEOFF
        self.log(f"plan: {len(P)} vertices, {prof.duration_s:.1f} s, land={land}")

    @staticmethod
    def _append(pts: list[np.ndarray], p: np.ndarray) -> int:
        if np.linalg.norm(p - pts[-1]) > 1e-3:
            pts.append(np.asarray(p, dtype=float))
        return len(pts) - 1

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
        speed = self.cruise if self.cruise is not None else self.param("MPC_XY_CRUISE")
        land = False
        hold = None
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
                if it.command == mav.MAV_CMD_NAV_WAYPOINT and it.params[0] > 0:
                    # a hold time: fly there, wait, then the rest (reached after the wait, as
                    # PX4 and ArduCopter report it: no mark here)
                    hold = (it.seq, float(it.params[0]))
            elif it.command == mav.MAV_CMD_DO_CHANGE_SPEED and it.params[1] > 0:
                speed = float(it.params[1])
            elif it.command == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
                # the return is flown at the autopilot's own speed
                speed = self.param("MPC_XY_CRUISE")
                z = max(pts[-1][2], self.param("RTL_RETURN_ALT"), 5.0)
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
            if hold is not None:
                break
            marks.append((len(pts) - 1, it.seq))
            if land:
                break
        self._start_plan(pts, marks, land, speeds)
        self.plan.hold = hold
        self.say("Executing Mission")
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
        z = max(self.pos[2], self.param("RTL_RETURN_ALT"), 5.0)
        self.say(f"RTL: start return at {z:.0f} m")
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
