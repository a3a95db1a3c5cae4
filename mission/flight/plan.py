"""The raw MAVLink mission for a ``MissionSpec``: take-off, cruise speed, waypoints, return or land.

Why raw items (``mission_raw``) rather than MAVSDK's high-level mission: ArduPilot needs a home item 0 and
a ``MAV_CMD_NAV_TAKEOFF``, which the high-level plugin cannot express (sitl/README.md, AUTOPILOTS notes).
Exactly one item carries ``current=1`` (MAVSDK refuses the upload otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAV_FRAME_GLOBAL, MAV_FRAME_MISSION, MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 0, 2, 6
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
CMD_WAYPOINT, CMD_RTL, CMD_LAND, CMD_TAKEOFF, CMD_CHANGE_SPEED = 16, 20, 21, 22, 178


@dataclass(frozen=True)
class RawItem:
    """Fields of MISSION_ITEM_INT (lat/lon as degrees * 1e7 integers)."""

    command: int
    frame: int
    x: int = 0
    y: int = 0
    z: float = 0.0
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)


def build_items(
    spec, home_lat: float, home_lon: float, home_alt_amsl: float, ardupilot: bool
) -> list[RawItem]:
    """Raw items for ``spec``: [home (ArduPilot)], take-off, speed, waypoints (frame 3), RTL (20) or land."""
    o = spec.field.origin
    wps = np.asarray(spec.waypoints_enu(), dtype=float)
    lat, lon, _ = o.to_geodetic(wps)
    lat, lon = np.atleast_1d(lat), np.atleast_1d(lon)
    e7 = lambda v: int(round(float(v) * 1e7))  # noqa: E731
    items: list[RawItem] = []
    if ardupilot:
        items.append(
            RawItem(CMD_WAYPOINT, MAV_FRAME_GLOBAL, e7(home_lat), e7(home_lon), float(home_alt_amsl))
        )
    items.append(
        RawItem(
            CMD_TAKEOFF,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            e7(home_lat),
            e7(home_lon),
            float(wps[0, 2]),
            (0.0, 0.0, 0.0, float("nan")),
        )
    )
    items.append(
        RawItem(CMD_CHANGE_SPEED, MAV_FRAME_MISSION, params=(1.0, float(spec.cruise_speed_mps), -1.0, 0.0))
    )
    for i in range(len(wps)):
        items.append(
            RawItem(
                CMD_WAYPOINT,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                e7(lat[i]),
                e7(lon[i]),
                float(wps[i, 2]),
                (0.0, 2.0, 0.0, float("nan")),
            )
        )
    if spec.return_behaviour == "land":
        items.append(RawItem(CMD_LAND, MAV_FRAME_GLOBAL_RELATIVE_ALT, e7(lat[-1]), e7(lon[-1]), 0.0))
    else:
        items.append(RawItem(CMD_RTL, MAV_FRAME_MISSION))
    return items


def to_mavsdk(items: list[RawItem]):
    """``mavsdk.plugins.mission_raw.MissionItem`` list; item 0 is the only one with current=1."""
    from mavsdk.plugins.mission_raw import MissionItem

    out = []
    for seq, it in enumerate(items):
        out.append(
            MissionItem(
                seq, it.frame, it.command, 1 if seq == 0 else 0, 1, *it.params, it.x, it.y, float(it.z), 0
            )
        )
    return out
