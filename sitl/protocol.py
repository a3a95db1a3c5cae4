"""The MAVLink vocabulary of the simulated vehicle: PX4 modes, sensor bits, default streams, mission
items.

Why a module of its own: the handlers, the mode machine, the stream scheduler and the dynamics all
speak it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

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

# AFAR field (Lake Wheeler), ground altitude 0 (relative use)
DEFAULT_HOME = (
    35.72744,
    -78.69607,
    0.0,
)
PHYSICS_DT = 0.01  # s of simulated time per physics step (100 Hz) up to speed-up 10
MAX_PHYSICS_DT = (
    0.05  # coarsest step at high speed-up (the attitude response is 0.8 s, turbulence 0.6 s)
)
# gust and turbulence correlation times; turbulence sd
WIND_TAU_S, TURB_TAU_S, TURB_DEG = (
    6.0,
    0.6,
    0.8,
)
# streams sent exactly at their requested rate in vehicle time; the others (status: GPS_RAW_INT,
# EXTENDED_SYS_STATE, ...) repeat the same content and are sent at most STATUS_WALL_HZ times per
# wall-clock second at high speed-up (the landed state is also sent at once whenever it changes)
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


@dataclass(frozen=True)
class Profile:
    """How the vehicle behaves beyond the protocol: ``default`` flies exactly the project's
    kinematics (the flown time matches the plan); ``px4`` behaves like PX4 v1.16 SITL as flown
    against the runner: legs at 93 % of the speed asked (corner smoothing and acceptance radii the
    plan does not model), the return and legs without a speed item at its ``MPC_XY_CRUISE``
    parameter (4.8 m/s unless set), STATUSTEXT gated on ground-station heartbeats
    (``sitl.statustext``), some texts with PX4's trailing tab."""

    name: str
    speed_factor: float = 1.0
    mpc_xy_cruise: float | None = None  # None: the kinematics' cruise speed
    gate_texts: bool = False
    tab_texts: bool = False
    # take-off speed, descent speed, final landing speed (m/s) and the height below which it lands
    # at the last one (PX4: MPC_TKO_SPEED, MPC_Z_V_AUTO_DN, MPC_LAND_SPEED, MPC_LAND_ALT2); None:
    # the kinematics' climb rate throughout
    vertical: tuple[float, float, float, float] | None = None
    # height above home a return climbs to first when lower (PX4: RTL_RETURN_ALT, 30 m on a v1.16
    # multicopter); 0: the return is flown at the altitude it starts from
    rtl_return_alt_m: float = 0.0


PROFILES = {
    "default": Profile("default"),
    "px4": Profile("px4", 0.93, 4.8, True, True, (1.5, 1.5, 0.7, 5.0), 30.0),
}
VERTICAL_PARAMS = ("MPC_TKO_SPEED", "MPC_Z_V_AUTO_DN", "MPC_LAND_SPEED", "MPC_LAND_ALT2")
# PX4 v1.16: no hover over home before landing (it is not flown here)
OTHER_PARAMS = {"RTL_LAND_DELAY": 0.0}


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
