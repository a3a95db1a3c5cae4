"""A simulated PX4-like MAVLink multicopter: mission protocol, commands, telemetry on a simulated
clock.

Why: ``fly-mission`` must be testable end to end (and usable for demos and training) without a real
autopilot, and it must exercise the same MAVLink paths as PX4 so that the runner is not written
against a toy.  The vehicle speaks MAVLink 2 over UDP and *sends* to the ground station's port,
exactly like PX4 SITL does: the ground station listens (MAVSDK ``udpin://0.0.0.0:14540``,
QGroundControl on 14550) and the vehicle answers whoever talks back to it.

One job per module: ``protocol`` (the MAVLink vocabulary), ``handlers`` (messages and commands in),
``mission_store`` (the mission protocol), ``modes`` (the mode machine and its plans), ``dynamics``
(motion, attitude, events), ``streams`` (telemetry out), ``cli`` (options); this module holds the
state and the main loop.  Simulated time runs ``--speedup`` times faster than the wall clock and is
the ``time_boot_ms`` of every message.

Run: ``python -m sitl.vehicle --port 14540 --speedup 5`` or ``rfsl sitl``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import select
import sys
import time

import numpy as np

from mission.geo import Origin
from mission.trajectory.attitude import AttitudeState
from mission.trajectory.kinematics import Kinematics
from sitl.cli import add_arguments, build_parser, parse_home, parse_kinematics
from sitl.dynamics import Dynamics
from sitl.handlers import MavlinkHandlers
from sitl.mission_store import MissionStore
from sitl.modes import ModeMachine
from sitl.params import ParamStore
from sitl.protocol import (
    DEFAULT_HOME,
    DEFAULT_INTERVALS,
    OTHER_PARAMS,
    PROFILES,
    PX4_AUTO_LOITER,
    PX4_MAIN_AUTO,
    VERTICAL_PARAMS,
    Item,
    Profile,
    mav,
    mavutil,
)
from sitl.statustext import StatusTexts
from sitl.streams import StreamScheduler

__all__ = [
    "SimVehicle",
    "Item",
    "add_arguments",
    "build_parser",
    "main",
    "parse_home",
    "parse_kinematics",
    "run_from_args",
]


class SimVehicle(
    MavlinkHandlers, MissionStore, ModeMachine, Dynamics, StreamScheduler, ParamStore, StatusTexts
):
    """State of one simulated multicopter (one MAVLink system, component 1) and its main loop."""

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
        profile: Profile | str = "default",
        statustext_log: str | None = None,
    ) -> None:
        self.conn = mavutil.mavlink_connection(
            url, source_system=sysid, source_component=1, dialect="common", autoreconnect=True
        )
        self.mav = self.conn.mav
        self.origin = Origin(*home)
        self.speedup = float(speedup)
        self.kin = kin or Kinematics()
        self.profile = PROFILES[profile] if isinstance(profile, str) else profile
        cruise = self.profile.mpc_xy_cruise or self.kin.cruise_speed_mps
        c = self.kin.climb_rate_mps
        vertical = self.profile.vertical or (c, c, c, 0.0)
        self.params = {
            "MPC_XY_CRUISE": float(cruise),
            **dict(zip(VERTICAL_PARAMS, map(float, vertical), strict=True)),
            **OTHER_PARAMS,
            "RTL_RETURN_ALT": float(self.profile.rtl_return_alt_m),
        }
        self.cruise: float | None = None  # set by MAV_CMD_DO_CHANGE_SPEED; None: MPC_XY_CRUISE
        self.verbose = verbose
        self.noise = np.random.default_rng(seed)  # wind gusts and turbulence
        self.gust_sigma = gust_mps
        # state
        self.sim_t = 0.0
        self.pos = np.zeros(3)
        self.armed = False
        self.main_mode, self.sub_mode = PX4_MAIN_AUTO, PX4_AUTO_LOITER
        self.plan = None
        self.items: list[Item] = []
        self.current_seq = 0
        self.landed_state = mav.MAV_LANDED_STATE_ON_GROUND
        self.disarm_at: float | None = None
        # (sim s, item seq): a waypoint's hold time ends then and the mission goes on
        self.resume: tuple[float, int] | None = None
        self.takeoff_alt = 2.5
        # attitude (mission.trajectory.attitude) and its drivers
        self.att_state = AttitudeState.at_rest(self.pos, 0.0)
        self.v_s = [0.0, 0.0, 0.0]  # smoothed velocity, ENU
        self.yaw = 0.0
        self.roll = self.pitch = 0.0
        self.wind = np.zeros(2)  # east, north (m/s)
        self.turb = np.zeros(2)  # pitch, roll (rad)
        # streams
        self.intervals = dict(DEFAULT_INTERVALS)
        self.next_due = dict.fromkeys(self.intervals, 0.0)
        self._rx: dict | None = None  # mission upload in progress
        self._wall_next = {"hb": 0.0, "sys": 0.0, "cur": 0.0}
        self.uploads = 0
        self._ess_sent = -1  # landed state last sent in EXTENDED_SYS_STATE
        self.init_texts(self.profile.gate_texts, statustext_log)

    def log(self, msg: str) -> None:
        if self.verbose:
            print(f"[sitl t={self.sim_t:8.2f}] {msg}", file=sys.stderr, flush=True)

    @property
    def t_ms(self) -> int:
        return int(round(self.sim_t * 1000))

    @property
    def flying(self) -> bool:
        return self.landed_state != mav.MAV_LANDED_STATE_ON_GROUND

    def run(self, duration_s: float | None = None, parent_pid: int | None = None) -> None:
        """Main loop: read MAVLink, advance simulated time with the wall clock times ``speedup``.

        With ``parent_pid`` the loop ends once that process is gone (checked every wall-clock
        second), so a vehicle started by ``fly-mission`` never outlives it, even after a ``kill
        -9``."""
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
            self.flush_texts()
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


def run_from_args(args: argparse.Namespace) -> int:
    """Build the vehicle from parsed options and run it until killed."""
    if args.speedup <= 0:
        raise ValueError("--speedup must be positive")

    home = parse_home(args.home) if args.home else DEFAULT_HOME
    url = args.url or f"udpout:{args.host}:{args.port}"
    kin = parse_kinematics(args.kinematics)
    if args.cruise_speed is not None:
        kin = dataclasses.replace(kin, cruise_speed_mps=float(args.cruise_speed))
    profile = PROFILES[args.profile]
    if args.speed_factor is not None:
        if not 0 < args.speed_factor <= 2:
            raise ValueError("--speed-factor must be in (0, 2]")
        profile = dataclasses.replace(profile, speed_factor=float(args.speed_factor))
    v = SimVehicle(
        url,
        home,
        args.speedup,
        args.seed,
        kin,
        gust_mps=args.gust,
        verbose=args.verbose,
        profile=profile,
        statustext_log=args.statustext_log,
    )
    print(
        f"sitl: simulated PX4 quadrotor ({profile.name} profile), MAVLink 2 on {url}, "
        f"home {home[0]:.6f},{home[1]:.6f}, speed-up {args.speedup:g}",
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
