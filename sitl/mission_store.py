"""Mission storage of the simulated vehicle: the MAVLink mission protocol (upload, download,
retries).

MISSION_COUNT -> MISSION_REQUEST_INT (MISSION_ITEM accepted too) -> MISSION_ACK;
MISSION_REQUEST_LIST download; geofence/rally types acknowledged and ignored.  A mixin of
``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

import time

from sitl.protocol import Item, mav


class MissionStore:
    """Stored items (``self.items``), the current item, and an upload in progress (``self._rx``)."""

    def on_mission_count(self, msg) -> None:
        mt = getattr(msg, "mission_type", 0)
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.count == 0:
            if mt == 0:
                self.items, self.current_seq = [], 0
            self.mav.mission_ack_send(*src, mav.MAV_MISSION_ACCEPTED, mt)
            return
        self._rx = {
            "type": mt,
            "count": msg.count,
            "items": [],
            "src": src,
            "asked": time.monotonic(),
            "tries": 0,
        }
        self.mav.mission_request_int_send(*src, 0, mt)

    def on_mission_item(self, msg) -> None:
        rx = self._rx
        if rx is None or getattr(msg, "mission_type", 0) != rx["type"]:
            return
        if msg.seq != len(rx["items"]):
            self.mav.mission_request_int_send(*rx["src"], len(rx["items"]), rx["type"])
            return
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":  # float lat/lon
            x, y = int(round(msg.x * 1e7)), int(round(msg.y * 1e7))
        rx["items"].append(
            Item(
                msg.seq,
                msg.frame,
                msg.command,
                msg.current,
                msg.autocontinue,
                (msg.param1, msg.param2, msg.param3, msg.param4),
                x,
                y,
                msg.z,
            )
        )
        if len(rx["items"]) < rx["count"]:
            rx["asked"], rx["tries"] = time.monotonic(), 0
            self.mav.mission_request_int_send(*rx["src"], len(rx["items"]), rx["type"])
            return
        self._rx = None
        if rx["type"] == 0:
            self.items = rx["items"]
            cur = [i.seq for i in self.items if i.current]
            self.current_seq = cur[0] if cur else 0
            self.uploads += 1
            self.log(f"mission uploaded: {len(self.items)} items")
        self.mav.mission_ack_send(*rx["src"], mav.MAV_MISSION_ACCEPTED, rx["type"])
        self.send_mission_current()

    def on_mission_request(self, msg) -> None:
        mt = getattr(msg, "mission_type", 0)
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if mt != 0 or not 0 <= msg.seq < len(self.items):
            self.mav.mission_ack_send(*src, mav.MAV_MISSION_INVALID_SEQUENCE, mt)
            return
        it = self.items[msg.seq]
        self.mav.mission_item_int_send(
            *src,
            it.seq,
            it.frame,
            it.command,
            int(it.seq == self.current_seq),
            it.autocontinue,
            *it.params,
            it.x,
            it.y,
            it.z,
            0,
        )

    def retry_upload(self, now: float) -> None:
        """Ask again for an item the ground station did not send (5 tries, 0.5 s apart), then
        cancel."""
        rx = self._rx
        if rx is not None and now - rx["asked"] > 0.5:
            rx["tries"] += 1
            if rx["tries"] > 5:
                self.mav.mission_ack_send(
                    *rx["src"], mav.MAV_MISSION_OPERATION_CANCELLED, rx["type"]
                )
                self._rx = None
            else:
                rx["asked"] = now
                self.mav.mission_request_int_send(*rx["src"], len(rx["items"]), rx["type"])
