"""Dynamics of the simulated vehicle: the plan flown in simulated time, its attitude, and flight
events.

Positions come vectorised from the current plan (``FlightProfile.position``); attitude from the
project's one attitude model (``mission.trajectory.attitude.run_attitude``, the same as the fast
simulator's) driven by Ornstein-Uhlenbeck wind gusts and turbulence; events (item reached, take-off
and landing transitions, auto-disarm) run only at the times where something can happen.  The physics
step is 10 ms of simulated time up to speed-up 10 and coarser above (at most 50 ms, never coarser
than the fastest requested position/attitude stream).  A mixin of ``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

import math

import numpy as np

from mission.trajectory.attitude import ou_process, run_attitude
from sitl.protocol import (
    FAST_STREAMS,
    MAX_PHYSICS_DT,
    PHYSICS_DT,
    PX4_AUTO_LOITER,
    PX4_AUTO_MISSION,
    PX4_MAIN_AUTO,
    TURB_DEG,
    TURB_TAU_S,
    WIND_TAU_S,
    mav,
)


class Dynamics:
    """Advancing simulated time: motion, attitude, events and the telemetry due on the way."""

    def _events(self) -> None:
        """Item reached, take-off/landing transitions and auto-disarm at the current simulated
        time."""
        pl = self.plan
        if pl is not None:
            tau = self.sim_t - pl.t0
            while pl.reach and pl.reach[0][0] <= tau:
                _, seq = pl.reach.pop(0)
                self._item_reached(seq)
            done = tau >= pl.profile.duration_s
            if self.flying:
                if self.landed_state == mav.MAV_LANDED_STATE_TAKEOFF and (
                    self.pos[2] > 1.0 or done
                ):
                    self.landed_state = mav.MAV_LANDED_STATE_IN_AIR
                    self.say("Takeoff detected" + self.tab)
                if pl.land_at_end:
                    i = int(np.searchsorted(pl.profile.t_vertex, tau, side="right")) - 1
                    # where the final descent starts
                    top = pl.profile.vertices[-1 - pl.land_legs][2]
                    if i >= pl.n_legs - pl.land_legs and self.pos[2] < top - 0.1:
                        self.landed_state = mav.MAV_LANDED_STATE_LANDING
            if done:
                if pl.land_at_end:
                    self.pos[2] = 0.0
                    self.landed_state = mav.MAV_LANDED_STATE_ON_GROUND
                    self.disarm_at = self.sim_t + 1.0
                    self.log("landed")
                    self.say("Landing detected" + self.tab)
                self.plan = None
                if self.flying:
                    self.pos = pl.profile.vertices[-1].copy()
                    if pl.hold is not None:  # at a waypoint with a hold time: wait there
                        self.resume = (self.sim_t + pl.hold[1], pl.hold[0])
        if self.resume is not None and self.sim_t >= self.resume[0]:
            seq, self.resume = self.resume[1], None
            if self.armed and self.flying and self.sub_mode == PX4_AUTO_MISSION:
                self._item_reached(seq)
                self.start_mission()
        if self.disarm_at is not None and self.sim_t >= self.disarm_at:
            self.disarm_at = None
            if self.armed and not self.flying:
                self.armed = False
                if self.sub_mode == PX4_AUTO_MISSION:
                    self.current_seq = len(self.items)  # mission finished
                self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_LOITER
                self.log("auto-disarmed")
                self.say("Disarmed by landing")
                self.send_heartbeat()

    def _item_reached(self, seq: int) -> None:
        """Mission item ``seq`` reached: the message, the next item current (a return announced)."""
        self.mav.mission_item_reached_send(seq)
        if (
            seq + 1 < len(self.items)
            and self.items[seq + 1].command == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH
        ):
            self.say(f"RTL: start return at {max(self.pos[2], 5.0):.0f} m")
        self.current_seq = seq + 1 if seq + 1 < len(self.items) else seq
        self.send_mission_current()

    @property
    def tab(self) -> str:
        """PX4 ends some texts with a tab (seen on PX4 v1.16 SITL); the PX4-like profile does
        too."""
        return "\t" if self.profile.tab_texts else ""

    def physics_dt(self) -> float:
        """Simulated seconds per physics step: 10 ms up to speed-up 10, coarser above (a multiple of
        10 ms, at most ``MAX_PHYSICS_DT`` and never coarser than the fastest requested
        position/attitude stream), so that the cost per wall-clock second stays bounded while the
        requested rates hold in vehicle time."""
        dt = min(PHYSICS_DT * max(self.speedup / 10.0, 1.0), MAX_PHYSICS_DT)
        fastest = min((iv for m, iv in self.intervals.items() if m in FAST_STREAMS), default=dt)
        return PHYSICS_DT * max(1, math.floor(min(dt, fastest) / PHYSICS_DT + 1e-6))

    def _next_event_time(self) -> float:
        """The simulated time at which ``_events`` must next run (item reached, plan end, landing,
        disarm)."""
        t = self.disarm_at if self.disarm_at is not None else math.inf
        if self.resume is not None:
            t = min(t, self.resume[0])
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
            t = min(t, pl.t0 + float(tv[min(max(pl.n_legs - pl.land_legs, 0), len(tv) - 1)]))
        return t

    def advance(self, target_t: float) -> None:
        """Step the simulation up to simulated time ``target_t``, emitting the due telemetry.

        The whole chunk (positions, wind, turbulence, attitude) is computed vectorised; the loop
        visits only the steps where an event or a stream is due.  Roll and pitch are zero on the
        ground."""
        dt = self.physics_dt()
        n = int((target_t - self.sim_t) / dt + 1e-9)
        if n <= 0:
            return
        times = self.sim_t + dt * np.arange(1, n + 1)
        plan0 = self.plan
        if plan0 is not None:
            P = plan0.profile.position(np.clip(times - plan0.t0, 0.0, None))
        else:
            P = np.repeat(self.pos[None, :], n, axis=0)
        lat, lon, _ = self.origin.to_geodetic(P)
        lat, lon = np.atleast_1d(lat), np.atleast_1d(lon)
        g = self.noise.standard_normal((n, 4))
        wind = ou_process(g[:, :2], dt, WIND_TAU_S, self.gust_sigma, self.wind)
        turb = ou_process(g[:, 2:], dt, TURB_TAU_S, math.radians(TURB_DEG), self.turb)
        att, vel, self.att_state = run_attitude(P, dt, self.kin, self.att_state, wind, turb)
        next_ev = self._next_event_time()
        next_st = min((self.next_due.get(m, 0.0) for m in self.intervals), default=math.inf)
        i = 0
        while True:
            i = max(i, int(np.searchsorted(times, min(next_ev, next_st) - 1e-9)))
            if i >= n:
                break
            self.sim_t = float(times[i])
            self.pos = P[i].copy()
            if self.sim_t + 1e-9 >= next_ev:
                self._events()
                next_ev = self._next_event_time()
                if self.landed_state != self._ess_sent:
                    self.send_by_id(mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)  # landed state: at once
            if self.sim_t + 1e-9 >= next_st:
                self._set_attitude(att[i], vel[i])
                next_st = self._send_due(float(lat[i]), float(lon[i]))
            i += 1
        self.sim_t = float(times[-1])
        self.pos = P[-1].copy()
        self._set_attitude(att[-1], vel[-1])
        self.wind, self.turb = wind[-1], turb[-1]

    def _set_attitude(self, att: np.ndarray, vel: np.ndarray) -> None:
        self.v_s = vel.tolist()
        self.yaw = float(att[2])
        self.roll, self.pitch = (float(att[0]), float(att[1])) if self.flying else (0.0, 0.0)
