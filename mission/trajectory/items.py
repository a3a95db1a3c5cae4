"""The one MAVLink item list of a ``MissionSpec``, shared by the upload (``mission.flight``) and the
exports.

Items: [home (ArduPilot upload, item 0 of a QGC WPL file)], take-off above home, cruise speed
(``MAV_CMD_DO_CHANGE_SPEED``), the waypoints (2 m acceptance radius, yaw unchanged), then return to
launch or a landing below the last waypoint.  Altitudes are relative to home (frame
``MAV_FRAME_GLOBAL_RELATIVE_ALT``): a waypoint's ENU height minus home's.  Raw items rather than
MAVSDK's high-level mission because ArduPilot needs a home item 0 and ``MAV_CMD_NAV_TAKEOFF``, which
the high-level plugin cannot express (sitl/README.md). The MAVLink numbers come from pymavlink's
common dialect (imported from the dialect module, not ``mavutil``, whose import picks the process's
MAVLink version once).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

MAV_FRAME_GLOBAL = mavlink.MAV_FRAME_GLOBAL
MAV_FRAME_MISSION = mavlink.MAV_FRAME_MISSION
MAV_FRAME_GLOBAL_RELATIVE_ALT = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
ACCEPTANCE_RADIUS_M = 2.0  # waypoint param2


@dataclass(frozen=True)
class RawItem:
    """Fields of MISSION_ITEM_INT (lat/lon as degrees * 1e7 integers)."""

    command: int
    frame: int
    x: int = 0
    y: int = 0
    z: float = 0.0
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    @property
    def lat_deg(self) -> float:
        return self.x / 1e7

    @property
    def lon_deg(self) -> float:
        return self.y / 1e7

    @property
    def has_position(self) -> bool:
        """Whether x, y, z are a position (the navigation items), not unused fields."""
        return self.frame != MAV_FRAME_MISSION


def _e7(deg: float) -> int:
    return int(round(float(deg) * 1e7))


def home_geodetic(spec) -> tuple[float, float, float]:
    """The spec's home as (lat, lon deg, altitude AMSL m)."""
    lat, lon, alt = spec.field.origin.to_geodetic(np.asarray(spec.home_enu, dtype=float))
    return float(lat), float(lon), float(alt)


def build_items(
    spec,
    home: tuple[float, float, float] | None = None,
    home_item: bool = False,
    hold_s: float = 0.0,
) -> list[RawItem]:
    """The raw items of ``spec``; ``home`` (lat, lon, alt AMSL) is the vehicle's (None: the
    spec's home), and ``home_item`` puts it first as item 0 (ArduPilot's convention, and a QGC
    WPL file's).  ``hold_s``: the vehicle waits that long at the last waypoint before the return
    (param1, PX4's hold time and ArduCopter's delay): an adaptive flight's time to upload the next
    round, which skips the rest of the wait (``mission.adaptive.rounds``)."""
    hlat, hlon, halt = home_geodetic(spec) if home is None else home
    wps = np.asarray(spec.waypoints_enu(), dtype=float)
    lat, lon, _ = spec.field.origin.to_geodetic(wps)
    lat, lon = np.atleast_1d(lat), np.atleast_1d(lon)
    rel = wps[:, 2] - float(np.asarray(spec.home_enu, dtype=float)[2])  # frame 3: height above home
    nan = float("nan")
    items: list[RawItem] = []
    if home_item:
        items.append(
            RawItem(
                mavlink.MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL, _e7(hlat), _e7(hlon), float(halt)
            )
        )
    items.append(
        RawItem(
            mavlink.MAV_CMD_NAV_TAKEOFF,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            _e7(hlat),
            _e7(hlon),
            float(rel[0]),
            (0.0, 0.0, 0.0, nan),
        )
    )
    # ground speed, no throttle
    items.append(
        RawItem(
            mavlink.MAV_CMD_DO_CHANGE_SPEED,
            MAV_FRAME_MISSION,
            params=(1.0, float(spec.cruise_speed_mps), -1.0, 0.0),
        )
    )
    for i in range(len(wps)):
        hold = float(hold_s) if i == len(wps) - 1 else 0.0
        items.append(
            RawItem(
                mavlink.MAV_CMD_NAV_WAYPOINT,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                _e7(lat[i]),
                _e7(lon[i]),
                float(rel[i]),
                (hold, ACCEPTANCE_RADIUS_M, 0.0, nan),
            )
        )
    if spec.return_behaviour == "land":
        items.append(
            RawItem(
                mavlink.MAV_CMD_NAV_LAND,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                _e7(lat[-1]),
                _e7(lon[-1]),
                0.0,
            )
        )
    else:
        items.append(RawItem(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_FRAME_MISSION))
    return items
