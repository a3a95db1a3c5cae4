"""The raw MAVLink mission as MAVSDK upload items: ``mission.trajectory.items.build_items`` (the one builder,
shared with ``rfsl export``) turned into ``mavsdk.plugins.mission_raw.MissionItem``.

Exactly one item carries ``current=1`` (MAVSDK refuses the upload otherwise).
"""

from __future__ import annotations

from mission.trajectory.items import RawItem


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
