"""Autopilot status texts of the simulated vehicle, optionally gated on ground-station heartbeats as
PX4 does.

Why: PX4 sends STATUSTEXT on a link only while a ground-station HEARTBEAT arrived there within the
last 2.5 s (of its own, i.e. simulated, time) and drops queued texts older than 5 s.  MAVSDK
heartbeats once per wall-clock second, i.e. every 10 simulated seconds at speed-up 10: most texts
were lost.  The PX4-like profile reproduces that gate so the runner's fix (heartbeats scaled with
the speed-up) is tested against it; every text generated is counted, and with ``--statustext-log``
written (sent or dropped) as one JSON line, so a test can check that every text sent reached the
ground station. A mixin of ``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

import json

from sitl.protocol import mav

GCS_TIMEOUT_S = (
    2.5  # simulated s: PX4 sends texts on a link only while a GCS heartbeat is this recent
)
MAX_AGE_S = 5.0  # simulated s: older queued texts are dropped
GCS_TYPE = mav.MAV_TYPE_GCS


class StatusTexts:
    """``say`` queues a text; ``flush_texts`` (every loop turn) sends or drops what is queued."""

    def init_texts(self, gated: bool, log_path: str | None) -> None:
        self.texts_gated = gated
        self.text_queue: list[tuple[float, str, int]] = []
        self.texts = {"generated": 0, "sent": 0, "dropped": 0}
        self.gcs_hb_t = -float("inf")  # simulated time of the last ground-station heartbeat
        self.gcs_heartbeats = 0
        self._text_log = open(log_path, "a", encoding="utf-8") if log_path else None  # noqa: SIM115

    def say(self, text: str, severity: int = mav.MAV_SEVERITY_INFO) -> None:
        self.texts["generated"] += 1
        self.text_queue.append((self.sim_t, text, severity))
        self.log(f"statustext: {text!r}")

    def on_heartbeat_in(self, msg) -> None:
        if msg.type == GCS_TYPE:
            self.gcs_hb_t = self.sim_t
            self.gcs_heartbeats += 1

    def gcs_connected(self) -> bool:
        return not self.texts_gated or self.sim_t - self.gcs_hb_t <= GCS_TIMEOUT_S

    def flush_texts(self) -> None:
        if not self.text_queue:
            return
        keep = []
        for t, text, sev in self.text_queue:
            if self.texts_gated and self.sim_t - t > MAX_AGE_S:
                self.texts["dropped"] += 1
                self._record(t, text, False)
            else:
                keep.append((t, text, sev))
        self.text_queue = keep
        if not self.gcs_connected():
            return
        for t, text, sev in keep:
            self.mav.statustext_send(sev, text.encode()[:50])
            self.texts["sent"] += 1
            self._record(t, text, True)
        self.text_queue = []

    def _record(self, t: float, text: str, sent: bool) -> None:
        if self._text_log is not None:
            self._text_log.write(
                json.dumps({"t_s": round(t, 3), "text": text, "sent": sent}) + "\n"
            )
            self._text_log.flush()
