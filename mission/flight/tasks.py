"""The concurrent concerns of a flight: telemetry streams, vehicle state, signals, the watchdog, events.

Why: each stream is one asyncio task (MAVSDK-Python example style) that only updates shared state
(``Telemetry``, ``PhaseTracker``, ``FlightStatus``, asyncio events); the runner (``runner.Runner``, which
inherits this) decides what to do with it.  The watchdog reports a lost link once (and shows it in the
status line), a silent receiver once, and MAVSDK's own warnings once each.
"""

from __future__ import annotations

import asyncio
import json
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from mission.flight.progress import FoldedTexts, fit_width

LINK_LOST_AFTER_S = 3.0
SOURCE_STALLED_AFTER_S = 2.0
EXIT_OK, EXIT_FAILED, EXIT_ABORTED, EXIT_LINK = 0, 1, 130, 3


class FlightError(Exception):
    """A flight that could not be flown or finished (exit code attached)."""

    def __init__(self, message: str, code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        self.code = code


@dataclass
class VehicleState:
    armed: bool = False
    was_armed: bool = False
    in_air: bool = False
    was_in_air: bool = False
    landed_state: str = "UNKNOWN"
    progress: tuple[int, int] = (0, 0)
    events: list[dict] = field(default_factory=list)


class FlightTasks:
    """State shared by the tasks of one flight, the tasks themselves, and the event log (sidecar events)."""

    def __init__(self) -> None:
        self.st = VehicleState()
        self.abort = asyncio.Event()
        self.abort_reason = ""
        self.link_dead = asyncio.Event()
        self.landed_disarmed = asyncio.Event()
        self.mission_done = asyncio.Event()
        self.armed_seen = asyncio.Event()  # the armed telemetry arrived (PX4 SITL: "armed" before "started")
        self.last_text_wall = -float("inf")  # monotonic time of the last autopilot text
        self.link_lost = False
        self.display = None
        self.sdklog = None
        self.source = None
        self._source_warned = False
        self.texts = FoldedTexts()  # autopilot texts on screen: repeats counted, not shown

    # ----------------------------------------------------------------- events and signals
    def event(self, kind: str, text: str, warn: bool = False, show: bool = True) -> None:
        """Record an event for the sidecar and show it (``show``) as one line, wrapped at 80 columns."""
        t = self.tel.clock.now()
        self.st.events.append({"t_vehicle_s": None if not np.isfinite(t) else round(t, 3), "kind": kind,
                               "text": text, "wall": time.time()})
        if warn:
            self.status.warnings.append(text)
        if show:
            self.say(("WARNING: " if warn else "") + text, "yellow" if warn else "")

    def say(self, line: str, style: str = "") -> None:
        """Show a line (not recorded), wrapped at 80 columns."""
        if self.display is not None:
            self.display.message(line, style)
        else:
            print(fit_width(line), file=sys.stderr, flush=True)

    def _on_signal(self, name: str) -> None:
        if self.abort.is_set():
            self.event("signal", f"{name} again: stop waiting for the landing")
            self.link_dead.set()
            return
        self.abort_reason = name
        if self.st.was_in_air:
            self.event("abort", f"{name} received: returning to launch")
        elif self.st.armed:
            self.event("abort", f"{name} received before take-off: disarming")
        else:
            self.event("abort", f"{name} received before take-off: stopping, nothing flown")
        self.abort.set()

    def _abort_before_takeoff(self) -> None:
        if self.abort.is_set():
            raise FlightError(f"aborted ({self.abort_reason}) before take-off: nothing was flown", EXIT_ABORTED)

    def start_telemetry_tasks(self, telemetry, mission_raw, direct) -> list[asyncio.Task]:
        """Subscribe to every stream at once (before arming, so the log starts on the ground)."""
        return [asyncio.create_task(c) for c in (
            self._positions(direct), self._attitudes(telemetry), self._armed(telemetry),
            self._landed(telemetry), self._progress(mission_raw), self._status_texts(telemetry), self._watchdog(),
        )]

    # ----------------------------------------------------------------- tasks
    async def _positions(self, direct) -> None:
        async for m in direct.subscribe_message("GLOBAL_POSITION_INT"):
            f = json.loads(m.fields_json)
            self.tel.add_position(f["time_boot_ms"] / 1000.0, f["lat"] * 1e-7, f["lon"] * 1e-7, f["alt"] / 1000.0,
                                  f["relative_alt"] / 1000.0)
            self.status.rel_alt = f["relative_alt"] / 1000.0

    async def _attitudes(self, telemetry) -> None:
        async for a in telemetry.subscribe_attitude_euler():
            self.tel.add_attitude(a.timestamp_us / 1e6, np.deg2rad(a.roll_deg), np.deg2rad(a.pitch_deg),
                                  np.deg2rad(a.yaw_deg))

    async def _armed(self, telemetry) -> None:
        async for armed in telemetry.subscribe_armed():
            if armed != self.st.armed:
                self.event("armed" if armed else "disarmed", "armed" if armed else "disarmed")
            self.st.armed = armed
            self.st.was_armed |= armed
            if armed:
                self.armed_seen.set()
            self._check_landed()

    async def _landed(self, telemetry) -> None:
        async for ls in telemetry.subscribe_landed_state():
            name = getattr(ls, "name", str(ls))
            self.st.landed_state = name
            self.st.in_air = name in ("IN_AIR", "TAKING_OFF", "LANDING")
            self.st.was_in_air |= self.st.in_air
            if self.st.was_armed or self.st.in_air:
                self.phases.on_landed_state(self.tel.clock.now(), name)
            self._show_stage()
            self._check_landed()

    def _show_stage(self) -> None:
        """Once armed, the status line's stage is the mission phase."""
        if self.st.was_armed:
            self.status.stage = self.phases.current

    def _check_landed(self) -> None:
        st = self.st
        if st.was_armed and st.was_in_air and not st.armed and st.landed_state == "ON_GROUND":
            self.landed_disarmed.set()

    async def _progress(self, mission_raw) -> None:
        async for p in mission_raw.subscribe_mission_progress():
            self.st.progress = (p.current, p.total)
            self.status.item, self.status.items = p.current, p.total
            if self.st.was_in_air:
                self.phases.on_progress(self.tel.clock.now(), p.current)
                self._show_stage()
            if p.total and p.current >= p.total - 1 and self.st.was_in_air:
                if not self.mission_done.is_set():
                    self.event("mission", f"last mission item ({p.current}) active: returning")
                self.mission_done.set()

    async def _status_texts(self, telemetry) -> None:
        async for s in telemetry.subscribe_status_text():
            self.last_text_wall = time.monotonic()
            text = f"autopilot: {s.text.rstrip()}"  # PX4 ends some with a tab
            self.event("statustext", text, show=self.texts.show(text))

    async def _logger(self) -> None:
        while True:
            await asyncio.sleep(0.2)
            self.rows.write()

    async def _watchdog(self) -> None:
        while True:
            await asyncio.sleep(0.25)
            self._watch_link()
            self._watch_source()
            if self.sdklog is not None and not self.link_lost:
                for text in self.sdklog.new_messages():
                    self.event("mavsdk", f"MAVSDK: {text}", warn=True)
            self.status.t_now = self.tel.clock.now() if self.tel.n_pos else 0.0
            if self.st.was_armed and (self.status.t_start is None or not np.isfinite(self.status.t_start)):
                self.status.t_start = self.status.t_now if self.tel.n_pos else None
            if self.display is not None:
                self.display.refresh()

    def _watch_link(self) -> None:
        silent = self.tel.clock.silent_for()
        if self.tel.n_pos and silent > LINK_LOST_AFTER_S and not self.link_lost:
            self.link_lost = self.status.link_lost = True
            self.event("link", f"MAVLink link lost (no telemetry for {silent:.0f} s); still logging", warn=True)
        elif self.link_lost and silent < 1.0:
            self.link_lost = self.status.link_lost = False
            if self.sdklog is not None:
                self.sdklog.new_messages()  # what MAVSDK said while the link was down is not news
            self.event("link", "MAVLink link restored", warn=True)
        if self.link_lost and silent > self.opts.link_timeout_s and not self.link_dead.is_set():
            self.event("link", f"no telemetry for {silent:.0f} s: giving up the flight", warn=True)
            self.link_dead.set()

    def _watch_source(self) -> None:
        src = self.source
        if src is None or src.needs_model or not self.st.was_armed or self.link_lost:
            return
        stalled = src.stalled_for()
        if stalled > SOURCE_STALLED_AFTER_S and not self._source_warned:
            self._source_warned = True
            self.event("rss", f"RSS source {src.kind} delivered nothing for {stalled:.0f} s", warn=True)
        elif stalled < 1.0 and self._source_warned:
            self._source_warned = False
            self.event("rss", f"RSS source {src.kind} delivering again", warn=True)

    # ----------------------------------------------------------------- waiting
    async def _wait(self, *events: asyncio.Event, timeout: float | None = None) -> asyncio.Event | None:
        """Wait until one of ``events`` is set (returns it) or the timeout passes (None)."""
        waits = {asyncio.ensure_future(e.wait()): e for e in events}
        try:
            await asyncio.wait(waits, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for w in waits:
                w.cancel()
        for e in events:
            if e.is_set():
                return e
        return None

    async def _race(self, coro, timeout: float | None = None, what: str = ""):
        """Await ``coro`` unless an abort comes first (then FlightError) or ``timeout`` passes."""
        task = asyncio.ensure_future(coro)
        ab = asyncio.ensure_future(self.abort.wait())
        done, _ = await asyncio.wait({task, ab}, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
        ab.cancel()
        if task in done:
            return task.result()
        task.cancel()
        self._abort_before_takeoff()
        raise FlightError(f"timed out waiting for {what}", EXIT_LINK)

    async def _healthy(self, telemetry) -> None:
        async for h in telemetry.subscribe_health():
            if h.is_global_position_ok and h.is_home_position_ok:
                return

    def _check_home(self, home) -> None:
        o = self.spec.field.origin
        enu = o.to_enu(home.latitude_deg, home.longitude_deg, home.absolute_altitude_m)
        d = float(np.hypot(enu[0] - self.spec.home_enu[0], enu[1] - self.spec.home_enu[1]))
        if d > 30.0:
            self.event("home", f"vehicle home is {d:.0f} m from the mission's home; take-off from there", warn=True)
