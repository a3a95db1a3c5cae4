"""One flight's shared state (``FlightContext``), its exit codes and errors, and the waits its
coroutines use.

Why: the concerns of a flight (telemetry streams, the watchdog, the log writer, live estimates, the
budget, an extension such as the adaptive rounds) are standalone coroutines under one
``asyncio.TaskGroup`` (``mission.flight.runner``); each reads and updates this one context, and none
holds a reference to a runner object.  The context records events (sidecar ``events`` and one line
each), owns the asyncio events the coroutines signal each other with, and says which autopilot flies
(``Autopilot``), not a raw item count.
"""

from __future__ import annotations

import asyncio
import sys
import time
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Protocol

import numpy as np

from mission.flight.phases import PhaseTracker
from mission.flight.progress import FlightStatus, FoldedTexts, fit_width
from mission.flight.telemetry import Telemetry

EXIT_OK, EXIT_FAILED, EXIT_ABORTED, EXIT_LINK = 0, 1, 130, 3
EXIT_LOG = 4  # flown, but the log is incomplete (a write failed)


class FlightError(Exception):
    """A flight that could not be flown or finished (exit code attached)."""

    def __init__(self, message: str, code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        self.code = code


class Autopilot(StrEnum):
    """The autopilot family on the link: it decides the mission's raw items (ArduPilot's item 0 is
    home) and which parameters set the return speed."""

    ARDUPILOT = "ardupilot"
    PX4 = "px4"  # PX4 and PX4-like vehicles (the built-in one)

    @property
    def waypoint_offset(self) -> int:
        """Raw items before the first waypoint: [home,] take-off, speed."""
        return 3 if self is Autopilot.ARDUPILOT else 2


# (vendor id, product id) of the built-in vehicle's AUTOPILOT_VERSION ("RF", "SL"): it speaks PX4's
# dialect but flies the mission's own kinematics and disarms at touchdown, so over --connect it gets
# no PX4 pace or disarm delay in the budget plan (mission.flight.budget)
BUILTIN_PRODUCT = (0x5246, 0x534C)


@dataclass
class VehicleState:
    armed: bool = False
    was_armed: bool = False
    in_air: bool = False
    was_in_air: bool = False
    landed_state: str = "UNKNOWN"
    progress: tuple[int, int] = (0, 0)
    events: list[dict] = field(default_factory=list)


class Extension(Protocol):
    """What a mission adds to a plain flight (``mission.adaptive.rounds.AdaptiveRounds``): the spec
    flown, the sidecar's trajectory record, its checks once the autopilot's plan is known, a
    coroutine run while the mission flies, its record and closing lines."""

    spec: Any  # the spec whose items are uploaded first (the adaptive survey)
    update_s: float  # live-estimate period (vehicle s)

    def trajectory_meta(self) -> dict: ...
    # FlightError (exit 2) refuses before the upload
    def check(self, ctx: FlightContext) -> None: ...
    # seconds the uploaded part waits at its last waypoint for the extension's next part
    def hold_s(self, ctx: FlightContext) -> float: ...
    async def fly(self, ctx: FlightContext, action, mission_raw) -> None: ...
    def record(self, ctx: FlightContext) -> tuple[str, dict]: ...
    def result_lines(self, ctx: FlightContext) -> list[str]: ...


@dataclass
class FlightContext:
    """Everything one flight's coroutines share: what is flown (``spec``, ``opts``), measured state
    (``tel``, ``st``, ``phases``), what is shown (``status``, ``display``), the log (``rows``: its
    writer and row joiner) and the flags the coroutines signal each other with."""

    spec: Any  # MissionSpec as uploaded (an extension may fly a part of ``full_spec``)
    opts: Any  # FlyOptions
    speedup: float
    url: str | None
    status: FlightStatus
    tel: Telemetry
    phases: PhaseTracker
    full_spec: Any = None
    extension: Extension | None = None
    st: VehicleState = field(default_factory=VehicleState)
    autopilot: Autopilot = Autopilot.PX4
    builtin_vehicle: bool = False  # the autopilot on the link is sitl.vehicle (BUILTIN_PRODUCT)
    abort: asyncio.Event = field(default_factory=asyncio.Event)
    abort_reason: str = ""
    link_dead: asyncio.Event = field(default_factory=asyncio.Event)
    landed_disarmed: asyncio.Event = field(default_factory=asyncio.Event)
    mission_done: asyncio.Event = field(default_factory=asyncio.Event)
    # PX4 SITL: "armed" before "started"
    armed_seen: asyncio.Event = field(default_factory=asyncio.Event)
    last_text_wall: float = -float("inf")  # monotonic time of the last autopilot text
    link_lost: bool = False
    left_flying: bool = False  # a second signal: the flight stopped waiting for the landing
    display: Any = None
    sdklog: Any = None
    source: Any = None  # the RSS source
    truth: dict | None = None
    rows: Any = None  # RowLogger once the log is open (its ``writer``: the FlightLogWriter)
    log_path: Any = None
    home: Any = None  # the vehicle's home (MAVSDK Position) once known
    # put back after the flight
    restore_params: dict[str, int | float] = field(default_factory=dict)
    budget: Any = None  # BudgetWatch once the plan is known
    live: Any = None  # LiveEstimates
    rate_requested: float = 0.0
    heartbeats_sent: int = 0
    vehicle_proc: Any = None
    source_warned: bool = False
    # background coroutines, cancelled at the close
    tasks: list[asyncio.Task] = field(default_factory=list)
    # autopilot texts on screen: repeats counted
    texts: FoldedTexts = field(default_factory=FoldedTexts)

    def __post_init__(self) -> None:
        if self.full_spec is None:
            self.full_spec = self.spec

    @property
    def ardupilot(self) -> bool:
        return self.autopilot is Autopilot.ARDUPILOT

    def abort_for(self, reason: str, text: str = "", warn: bool = False) -> None:
        """Abort the flight (return to launch once airborne) for ``reason``, which the closing
        status and exit code name; ``text``, when given, is said as the ``abort`` event.  One home
        for a signal, a failed log write and the flight's own watch (stall, overdue)."""
        self.abort_reason = reason
        if text:
            self.event("abort", text, warn=warn)
        self.abort.set()

    def event(self, kind: str, text: str, warn: bool = False, show: bool = True) -> None:
        """Record an event for the sidecar and show it (``show``) as one line, wrapped at 80
        columns."""
        # no extrapolated time stamps
        t = self.tel.clock.now() if not self.link_lost else float("nan")
        e = {
            "t_vehicle_s": None if not np.isfinite(t) else round(t, 3),
            "kind": kind,
            "text": text,
            "wall": time.time(),
        }
        if self.link_lost:  # what was measured: the last telemetry's time
            last = self.tel.clock.last_measured()
            e["last_telemetry_vehicle_s"] = round(last, 3) if np.isfinite(last) else None
        self.st.events.append(e)
        if warn:
            self.status.warnings.append(text)
        if show:
            self.say(("WARNING: " if warn else "") + text, "yellow" if warn else "")

    def say(self, line: str, style: str = "") -> None:
        """Show a line (not recorded), wrapped at 80 columns."""
        try:
            if self.display is not None:
                self.display.message(line, style)
            else:
                print(fit_width(line), file=sys.stderr, flush=True)
        # a lost terminal (SIGHUP): the event is in the sidecar, flying goes on
        except (
            OSError,
            ValueError,
        ):
            pass

    def vehicle_state(self) -> str:
        """What is known of the vehicle at the end: ``landed``, ``on the ground`` (never flew), ``in
        flight`` (left flying, link alive) or ``unknown`` (the link was lost while it flew)."""
        if self.landed_disarmed.is_set():
            return "landed"
        if not self.st.was_in_air:
            return "on the ground"
        return (
            "unknown"
            if self.link_lost or (self.link_dead.is_set() and not self.left_flying)
            else "in flight"
        )

    def where(self) -> str:
        """The vehicle's last measured altitude and phase ("15 m in return")."""
        return f"{self.status.rel_alt:.0f} m in {self.phases.current}"

    def abort_before_takeoff(self) -> None:
        """Raise the abort (exit 130) when one came before the vehicle took off."""
        if self.abort.is_set():
            raise FlightError(
                f"aborted ({self.abort_reason}) before take-off: nothing was flown", EXIT_ABORTED
            )


async def wait_any(*events: asyncio.Event, timeout: float | None = None) -> asyncio.Event | None:
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


async def race(ctx: FlightContext, coro, timeout: float | None = None, what: str = ""):
    """Await ``coro`` unless an abort comes first (then FlightError) or ``timeout`` passes."""
    task = asyncio.ensure_future(coro)
    ab = asyncio.ensure_future(ctx.abort.wait())
    done, _ = await asyncio.wait({task, ab}, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
    ab.cancel()
    if task in done:
        return task.result()
    task.cancel()
    ctx.abort_before_takeoff()
    raise FlightError(f"timed out waiting for {what}", EXIT_LINK)
