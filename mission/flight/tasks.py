"""The concurrent concerns of a flight: telemetry streams, vehicle state, signals, the watchdog, the
log writer.

Why: each stream is one standalone coroutine (MAVSDK-Python example style) that only updates the
shared ``FlightContext`` (``Telemetry``, ``PhaseTracker``, ``FlightStatus``, asyncio events); the
flight's order (``mission.flight.runner``) decides what to do with it.  The watchdog reports a lost
link once (and shows it in the status line), a silent receiver once, and MAVSDK's own warnings once
each.  ``guarded`` wraps each one so that a failing stream is one warning, never the end of the
flight.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time

import numpy as np

from mission.flight.context import FlightContext

LINK_LOST_AFTER_S = 3.0
SOURCE_STALLED_AFTER_S = 2.0


async def guarded(ctx: FlightContext, coro, name: str) -> None:
    """Run one background coroutine; an exception in it is one warning, not a cancelled flight."""
    try:
        await coro
    except asyncio.CancelledError:
        raise
    except Exception as e:
        ctx.event("task", f"{name} stopped ({type(e).__name__}: {e})", warn=True)


def spawn(ctx: FlightContext, tg: asyncio.TaskGroup, coro, name: str) -> asyncio.Task:
    """Start a background coroutine of the flight in its task group (cancelled by the close)."""
    task = tg.create_task(guarded(ctx, coro, name), name=name)
    ctx.tasks.append(task)
    return task


def on_signal(ctx: FlightContext, name: str) -> None:
    """SIGINT/SIGTERM/SIGHUP: the first one aborts (return to launch once airborne), a second one
    stops the wait for the landing."""
    if ctx.abort.is_set():
        if ctx.st.in_air:
            ctx.left_flying = True
            ctx.event(
                "signal", f"{name} again: landing not awaited; vehicle at {ctx.where()}", warn=True
            )
        else:
            ctx.event("signal", f"{name} again: stop waiting for the landing")
        ctx.link_dead.set()
        return
    if ctx.st.was_in_air:
        ctx.abort_for(name, f"{name} received: returning to launch")
    elif ctx.st.armed:
        ctx.abort_for(name, f"{name} received before take-off: disarming")
    else:
        ctx.abort_for(name, f"{name} received before take-off: stopping, nothing flown")


def start_telemetry(
    ctx: FlightContext, tg: asyncio.TaskGroup, telemetry, mission_raw, direct, texts=None
) -> None:
    """Subscribe to every stream at once (before arming, so the log starts on the ground); the
    autopilot's texts from ``texts`` (a ``TelemetryAsync`` of their own MAVSDK instance:
    ``mission.flight.textlink``) when given."""
    for name, coro in (
        ("positions", positions(ctx, direct)),
        ("attitudes", attitudes(ctx, telemetry)),
        ("armed", armed(ctx, telemetry)),
        ("landed state", landed(ctx, telemetry)),
        ("mission progress", progress(ctx, mission_raw)),
        ("status texts", status_texts(ctx, texts or telemetry)),
        ("watchdog", watchdog(ctx)),
    ):
        spawn(ctx, tg, coro, name)


async def positions(ctx: FlightContext, direct) -> None:
    async for m in direct.subscribe_message("GLOBAL_POSITION_INT"):
        f = json.loads(m.fields_json)
        ctx.tel.add_position(
            f["time_boot_ms"] / 1000.0,
            f["lat"] * 1e-7,
            f["lon"] * 1e-7,
            f["alt"] / 1000.0,
            f["relative_alt"] / 1000.0,
        )
        ctx.status.rel_alt = f["relative_alt"] / 1000.0


async def attitudes(ctx: FlightContext, telemetry) -> None:
    async for a in telemetry.subscribe_attitude_euler():
        ctx.tel.add_attitude(
            a.timestamp_us / 1e6,
            np.deg2rad(a.roll_deg),
            np.deg2rad(a.pitch_deg),
            np.deg2rad(a.yaw_deg),
        )


async def armed(ctx: FlightContext, telemetry) -> None:
    async for is_armed in telemetry.subscribe_armed():
        if is_armed != ctx.st.armed:
            ctx.event("armed" if is_armed else "disarmed", "armed" if is_armed else "disarmed")
        ctx.st.armed = is_armed
        ctx.st.was_armed |= is_armed
        if is_armed:
            ctx.armed_seen.set()
        _check_landed(ctx)


async def landed(ctx: FlightContext, telemetry) -> None:
    async for ls in telemetry.subscribe_landed_state():
        name = getattr(ls, "name", str(ls))
        ctx.st.landed_state = name
        ctx.st.in_air = name in ("IN_AIR", "TAKING_OFF", "LANDING")
        ctx.st.was_in_air |= ctx.st.in_air
        if ctx.st.was_armed or ctx.st.in_air:
            ctx.phases.on_landed_state(ctx.tel.clock.now(), name)
        _show_stage(ctx)
        _check_landed(ctx)


def _show_stage(ctx: FlightContext) -> None:
    """Once armed, the status line's stage is the mission phase."""
    if ctx.st.was_armed:
        ctx.status.stage = ctx.phases.current


def _check_landed(ctx: FlightContext) -> None:
    st = ctx.st
    if st.was_armed and st.was_in_air and not st.armed and st.landed_state == "ON_GROUND":
        ctx.landed_disarmed.set()


async def progress(ctx: FlightContext, mission_raw) -> None:
    async for p in mission_raw.subscribe_mission_progress():
        ctx.st.progress = (p.current, p.total)
        ctx.status.item, ctx.status.items = p.current, p.total
        if ctx.st.was_in_air:
            ctx.phases.on_progress(ctx.tel.clock.now(), p.current)
            _show_stage(ctx)
        if p.total and p.current >= p.total - 1 and ctx.st.was_in_air:
            if not ctx.mission_done.is_set():
                ctx.event("mission", f"last mission item ({p.current}) active: returning")
            ctx.mission_done.set()


async def status_texts(ctx: FlightContext, telemetry) -> None:
    async for s in telemetry.subscribe_status_text():
        ctx.last_text_wall = time.monotonic()
        text = f"autopilot: {s.text.rstrip()}"  # PX4 ends some with a tab
        ctx.event("statustext", text, show=ctx.texts.show(text))  # recorded always, shown once


async def logger(ctx: FlightContext) -> None:
    """The log writer: every 0.2 s the rows the telemetry covers."""
    while True:
        await asyncio.sleep(0.2)
        ctx.rows.write()


def log_failed(ctx: FlightContext, error: OSError) -> None:
    """A log write failed (disk full, file-size limit): said at once (a warning, the status line,
    the sidecar); by default the flight returns to launch (``logging.on_write_error: continue``
    flies on).  Once."""
    if ctx.status.log_error:
        return
    why = error.strerror or type(error).__name__
    ctx.status.log_error = why
    w = ctx.rows.writer
    keep_flying = ctx.spec.on_write_error == "continue"
    then = (
        "flying on (logging.on_write_error: continue)"
        if keep_flying
        else "returning to launch"
        if ctx.st.was_in_air
        else "stopping"
    )
    ctx.event("log", f"log write failed ({why}): {w.rows} rows kept; {then}", warn=True)
    # a full disk may refuse the sidecar too: the line above still said it
    with contextlib.suppress(OSError):
        w.update_meta(
            log_error={
                "error": why,
                "rows_kept": w.rows,
                "policy": ctx.spec.on_write_error,
                "t_vehicle_s": ctx.st.events[-1]["t_vehicle_s"],
            }
        )
    if not keep_flying and not ctx.abort.is_set():
        ctx.abort_for("log write failed")


async def watchdog(ctx: FlightContext) -> None:
    while True:
        await asyncio.sleep(0.25)
        _watch_link(ctx)
        _watch_source(ctx)
        if ctx.sdklog is not None and not ctx.link_lost:
            for text in ctx.sdklog.new_messages():
                ctx.event("mavsdk", f"MAVSDK: {text}", warn=True)
        s = ctx.status
        s.t_now = ctx.tel.clock.now() if ctx.tel.n_pos else 0.0
        if ctx.st.was_armed and (s.t_start is None or not np.isfinite(s.t_start)):
            s.t_start = s.t_now if ctx.tel.n_pos else None
        if ctx.display is not None:
            # a lost terminal must not stop the watchdog
            with contextlib.suppress(OSError, ValueError):
                ctx.display.refresh()


def _watch_link(ctx: FlightContext) -> None:
    silent = ctx.tel.clock.silent_for()
    if ctx.tel.n_pos and silent > LINK_LOST_AFTER_S and not ctx.link_lost:
        ctx.link_lost = ctx.status.link_lost = True
        ctx.event(
            "link", f"MAVLink link lost (no telemetry for {silent:.0f} s); still logging", warn=True
        )
    elif ctx.link_lost and silent < 1.0:
        ctx.link_lost = ctx.status.link_lost = False
        if ctx.sdklog is not None:
            ctx.sdklog.new_messages()  # what MAVSDK said while the link was down is not news
        ctx.event("link", "MAVLink link restored", warn=True)
    if ctx.link_lost and silent > ctx.opts.link_timeout_s and not ctx.link_dead.is_set():
        ctx.event("link", f"no telemetry for {silent:.0f} s: giving up the flight", warn=True)
        ctx.link_dead.set()


def _watch_source(ctx: FlightContext) -> None:
    src = ctx.source
    if src is None or src.needs_model or not ctx.st.was_armed or ctx.link_lost:
        return
    stalled = src.stalled_for()
    if stalled > SOURCE_STALLED_AFTER_S and not ctx.source_warned:
        ctx.source_warned = True
        ctx.event("rss", f"RSS source {src.kind} delivered nothing for {stalled:.0f} s", warn=True)
    elif stalled < 1.0 and ctx.source_warned:
        ctx.source_warned = False
        ctx.event("rss", f"RSS source {src.kind} delivering again", warn=True)


async def healthy(telemetry) -> None:
    """Returns once the autopilot reports a usable global position and home."""
    async for h in telemetry.subscribe_health():
        if h.is_global_position_ok and h.is_home_position_ok:
            return
