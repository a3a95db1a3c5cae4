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



class UploadFailed(Exception):
    """A mission upload the autopilot refused or let time out, in one line: the result's name (TIMEOUT,
    PROTOCOL_ERROR...) and the item count, never the object reprs of MAVSDK's own message (3.5 kB on
    ArduPilot)."""


async def upload_items(mission_raw, items: list[RawItem], attempts: int = 3, on_retry=None) -> None:
    """Upload ``items`` (``MissionRawAsync.upload_mission``), retrying a failed transfer (a busy link at a high
    speed-up can time one out); ``on_retry(result_name)`` before each retry; ``UploadFailed`` after the last."""
    from mavsdk.plugins.mission_raw import MissionRawError

    for attempt in range(attempts):
        try:
            await mission_raw.upload_mission(to_mavsdk(items))
            return
        except MissionRawError as e:
            name = getattr(getattr(e, "result", None), "name", None) or type(e).__name__
            if attempt == attempts - 1:
                raise UploadFailed(f"mission upload failed: {name}, {len(items)} items") from None
            if on_retry is not None:
                on_retry(name)
