"""The raw MAVLink mission as MAVSDK upload items: ``mission.trajectory.items.build_items`` (the one builder,
shared with ``rfsl export``) turned into ``mavsdk.plugins.mission_raw.MissionItem``.

Exactly one item carries ``current=1`` (MAVSDK refuses the upload otherwise).  ``upload_with_retries``: the one
upload of a flight (the mission, then each adaptive round).
"""

from __future__ import annotations

from mission.flight.context import EXIT_LINK, FlightError
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


async def upload_with_retries(ctx, mission_raw, items: list[RawItem], kind: str = "upload", tries: int = 3) -> None:
    """Upload the raw items, retrying a failed transfer (a busy link at a high speed-up can time one out) with
    one warning each; the last failure is a ``FlightError`` (exit 3) naming MAVSDK's result."""
    from mavsdk.plugins.mission_raw import MissionRawError

    for attempt in range(tries):
        try:
            await mission_raw.upload_mission(to_mavsdk(items))
            return
        except MissionRawError as e:
            if attempt == tries - 1:
                raise FlightError(f"mission upload failed: {e.result.name}", EXIT_LINK) from None
            ctx.event(kind, f"mission upload failed ({e.result.name}); retrying", warn=True)
