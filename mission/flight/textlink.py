"""The autopilot's texts on a MAVSDK instance of their own, so that a telemetry flood cannot drop
them.

Why: MAVSDK v4 calls every subscription callback of an instance from one thread through one queue;
each call needs Python's GIL.  When that thread falls behind (a busy CPU, the loop holding the GIL)
and 100 callbacks are queued, MAVSDK drops the oldest subscription updates, whichever subscription
they belong to ("Dropping subscription callbacks (N so far)").  Position and attitude arrive by the
hundred per wall second at a high speed-up, so an autopilot text queued among them was dropped too:
PX4 SITL at 10x on a loaded 2-core machine lost 5 of 9 texts.  Here the flight's instance forwards
every message it receives to a second instance on a local UDP port (``ForwardingOption.ON`` on
that connection only, so nothing from the second instance reaches the autopilot); the second one
subscribes to the texts alone, so its queue never holds more than a few, and none is dropped.
Measured against PX4 SITL at 10x with the GIL held for a second at a time (arming and disarming
twice): the flight's instance dropped 12,000 callbacks and all 5 texts, the text instance kept 4
(that probe sent no ground-station heartbeat of its own, which PX4 needs before it sends texts).
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator

from mavsdk.asyncio import ComponentType, Configuration, ForwardingOption, Mavsdk
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

from mission.flight.vehicle_process import free_udp_port

TEXT_LINK_SYSID = 246  # the second instance's system id (the flight's is MAVSDK's 245)


@contextlib.asynccontextmanager
async def text_link(sdk, timeout_s: float = 10.0) -> AsyncIterator[object | None]:
    """A ``TelemetryAsync`` on a second MAVSDK instance fed by ``sdk`` (already connected to the
    autopilot), or None when it saw no autopilot within ``timeout_s`` (the flight then takes the
    texts from its own instance)."""

    port = free_udp_port()
    cfg = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    cfg.system_id = TEXT_LINK_SYSID
    async with Mavsdk(cfg) as texts_sdk:
        try:
            await texts_sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
            await sdk.add_any_connection(f"udpout://127.0.0.1:{port}", ForwardingOption.ON)
            system = await texts_sdk.first_autopilot(timeout_s=timeout_s)
        except Exception:  # a connection refused: the flight's own instance carries the texts
            system = None
        yield None if system is None else TelemetryAsync(system)
