"""The ground station's heartbeat at the vehicle's pace, and the autopilot's last texts awaited
before landing is announced.

Why: PX4 sends STATUSTEXT on a link only while a ground-station HEARTBEAT arrived within the last
2.5 s of its own time, and drops queued texts older than 5 s; MAVSDK heartbeats once per wall-clock
second, i.e. every 10 vehicle seconds at speed-up 10, and 2 to 7 of 9 texts were lost.  This task
sends the ground station's HEARTBEAT (MAVSDK v4's ``MavlinkDirectAsync.send_message``, same system
and component id as MAVSDK's own: 245/190) once per *vehicle* second, i.e. ``speed-up`` times per
wall second.  It runs on a thread of its own, not on the event loop, so that a loop busy for a few
tenths of a second (an upload, an estimate returning) does not close PX4's gate: at 10x that gate
is 0.25 wall s.  Measured on the 2-core development machine at load 8-12 with this thread and the
texts on their own MAVSDK instance: PX4 SITL at 10x still lost 0, 2, 2 and 4 texts in 4 flights
(PX4 itself, starved, is the likelier cause), at 5x none in 4 flights.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time

from mavsdk.plugins.mavlink_direct import MavlinkMessage

GCS_SYSID, GCS_COMPID = 245, 190  # MAVSDK's ground-station identity
# MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, MAV_STATE_ACTIVE
_HEARTBEAT = json.dumps(
    {
        "type": 6,
        "autopilot": 8,
        "base_mode": 0,
        "custom_mode": 0,
        "system_status": 4,
        "mavlink_version": 3,
    }
)


PER_VEHICLE_S = (
    3.0  # heartbeats per vehicle second: a late one (a starved CPU) still leaves the gate open
)


def heartbeat_hz(speedup: float) -> float:
    """Wall-clock rate: three heartbeats per vehicle second (at least 1 Hz), well inside PX4's 2.5 s
    even when the loop runs a few heartbeats late (PX4 SITL at 10x on two loaded cores lost 3 to 6
    of 12 texts at one a vehicle second)."""
    return max(1.0, PER_VEHICLE_S * float(speedup))


async def gcs_heartbeats(ctx, direct, speedup: float) -> None:
    """Task: HEARTBEAT to the vehicle at ``heartbeat_hz(speedup)`` from a thread (MAVSDK's blocking
    ``send_message`` releases the GIL), until cancelled; a failure is reported once."""

    msg = MavlinkMessage("HEARTBEAT", GCS_SYSID, GCS_COMPID, 0, 0, _HEARTBEAT)
    period, stop = 1.0 / heartbeat_hz(speedup), threading.Event()
    loop = asyncio.get_running_loop()
    send = direct._plugin  # MavlinkDirectAsync (mavsdk 4.1) wraps the blocking MavlinkDirect

    def failed(e: Exception) -> None:
        ctx.event("heartbeat", f"GCS heartbeat not sent ({e}): autopilot texts may be lost", True)

    def beat() -> None:
        said = False
        while not stop.is_set():
            try:
                send.send_message(msg)
                ctx.heartbeats_sent += 1
            except Exception as e:
                if not said:
                    said = True
                    loop.call_soon_threadsafe(failed, e)
            stop.wait(period)

    thread = threading.Thread(target=beat, name="gcs-heartbeat", daemon=True)
    thread.start()
    try:
        await asyncio.Event().wait()  # until the flight's close cancels the task
    finally:
        stop.set()


async def settle_texts(ctx, speedup: float, quiet_s: float = 0.3, most_s: float = 3.0) -> None:
    """Wait (wall clock) until no autopilot text arrived for ``quiet_s`` and at least 2 vehicle
    seconds have passed, at most ``most_s``: the texts sent around the disarm ("Disarmed by
    landing") are then logged before "landed and disarmed", not after it."""
    t0 = time.monotonic()
    least = min(2.0 / max(speedup, 1e-9), most_s)
    while time.monotonic() - t0 < most_s:
        now = time.monotonic()
        if now - t0 >= least and now - ctx.last_text_wall >= quiet_s:
            return
        await asyncio.sleep(0.05)
