"""The raw MAVLink mission as MAVSDK upload items: ``mission.trajectory.items.build_items`` (the one
builder, shared with ``rfsl export``) turned into ``mavsdk.plugins.mission_raw.MissionItem``.

Exactly one item carries ``current=1`` (MAVSDK refuses the upload otherwise).
``upload_with_retries``: the one upload of a flight (the mission, each adaptive round, a budget
trim); its last failure is one line (``UploadFailed``).
"""

from __future__ import annotations

from mavsdk.plugins.mission_raw import MissionItem, MissionRawError

from mission.flight.context import EXIT_LINK, FlightError
from mission.trajectory.items import RawItem


def to_mavsdk(items: list[RawItem]):
    """``mavsdk.plugins.mission_raw.MissionItem`` list; item 0 is the only one with current=1."""
    out = []
    for seq, it in enumerate(items):
        out.append(
            MissionItem(
                seq,
                it.frame,
                it.command,
                1 if seq == 0 else 0,
                1,
                *it.params,
                it.x,
                it.y,
                float(it.z),
                0,
            )
        )
    return out


class UploadFailed(FlightError):
    """A mission upload the autopilot refused or let time out, in one line (exit 3): the result's
    name (TIMEOUT, PROTOCOL_ERROR...) and the item count, never the object reprs of MAVSDK's own
    message (3.5 kB on ArduPilot)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, EXIT_LINK)


async def upload_with_retries(
    ctx, mission_raw, items: list[RawItem], kind: str = "upload", tries: int = 3
) -> None:
    """Upload the raw items (``MissionRawAsync.upload_mission``), retrying a failed transfer (a busy
    link at a high speed-up can time one out) with one warning each (event ``kind``); the last
    failure is an ``UploadFailed`` naming MAVSDK's result and the item count."""
    for attempt in range(tries):
        try:
            await mission_raw.upload_mission(to_mavsdk(items))
            return
        except MissionRawError as e:
            name = getattr(getattr(e, "result", None), "name", None) or type(e).__name__
            if attempt == tries - 1:
                raise UploadFailed(f"mission upload failed: {name}, {len(items)} items") from None
            ctx.event(kind, f"mission upload failed ({name}); retrying", warn=True)
