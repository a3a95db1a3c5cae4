"""The asyncio flight on MAVSDK v4: connect, check, upload, arm, fly, log RSS, return, land, close.

Why this shape: one ``FlightContext`` (``mission.flight.context``) and standalone coroutines over it
under one ``asyncio.TaskGroup``: one per telemetry stream (``tasks``), the log writer, the
watchdog/display, the budget watch, the live estimates (``estimates``) and a mission's extension
(the adaptive rounds, ``mission.adaptive.rounds``), so a slow or silent part (a stalled receiver, a
lost link) never blocks the others; every exit path (end of mission, Ctrl-C/SIGTERM/SIGHUP, link
loss, an exception) goes through one ``finally`` that commands return-to-launch if the vehicle is
still flying, waits for the landing (bounded) and closes the log.  Telemetry is subscribed right
after connecting, so the log starts on the ground before arming.  Options are checked
(``preflight``) before anything starts.  Times are the vehicle's clock (``time_boot_ms``); the
sidecar records the measured speed-up and telemetry rates.

MAVSDK v4 API used (native binding, ``mavsdk.asyncio``):
``Mavsdk(Configuration.create_with_component_type( ComponentType.GROUND_STATION))`` as an async
context manager, ``add_any_connection``, ``first_autopilot``; ``TelemetryAsync`` (health, home,
attitude_euler, armed, landed_state, set_rate_*), ``ActionAsync`` (arm, disarm, return_to_launch),
``MissionRawAsync`` (upload_mission, start_mission, subscribe_mission_progress), ``ParamAsync``
(ArduPilot return settings) and ``MavlinkDirectAsync`` (GLOBAL_POSITION_INT with its
``time_boot_ms``, which the Telemetry plugin's position lacks).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mavsdk.asyncio import Autopilot as SdkAutopilot
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.info import InfoAsync
from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.action import ActionError
from mavsdk.plugins.mission_raw import MissionRawError

from mission.errors import InputError
from mission.flight import estimates, tasks
from mission.flight.budget import (
    OVERDUE,
    TAKEOFF_STALLED,
    close_budget,
    start_budget,
    watch_budget,
)
from mission.flight.context import (
    BUILTIN_PRODUCT,
    EXIT_ABORTED,
    EXIT_FAILED,
    EXIT_LINK,
    EXIT_LOG,
    EXIT_OK,
    Autopilot,
    FlightContext,
    FlightError,
    race,
    wait_any,
)
from mission.flight.estimates import LiveEstimates
from mission.flight.heartbeat import gcs_heartbeats, settle_texts
from mission.flight.logrows import RowLogger, new_flight_dir
from mission.flight.phases import MonotonicPhases, final_phase
from mission.flight.plan import upload_with_retries
from mission.flight.preflight import check_options
from mission.flight.progress import Display, FlightStatus
from mission.flight.sdklog import SdkLog
from mission.flight.signals import LoopSignals
from mission.flight.sources import SimSource, make_receiver, parse_source
from mission.flight.speeds import apply_speeds, restore_speeds, vertical_speeds
from mission.flight.telemetry import Telemetry
from mission.flight.textlink import text_link
from mission.flight.vehicle_process import (
    free_udp_port,
    ignore_terminal_signals,
    spawn_vehicle,
    stop_vehicle,
)
from mission.flightlog import PHASE_COLUMNS, FlightLogWriter, make_meta
from mission.trajectory.checks import assert_flyable
from mission.trajectory.items import build_items

__all__ = [
    "FlyOptions",
    "auto_rate_hz",
    "fly",
    "free_udp_port",
    "spawn_vehicle",
    "wall_clock_notice",
]

# position/attitude rate requested (vehicle time); the floor
RATE_HZ, MIN_RATE_HZ = (
    50.0,
    30.0,
)
WALL_CALLBACKS_PER_STREAM = (
    600.0  # at most this many per wall-clock second per stream (sped-up vehicles)
)
FIRST_ROW_TIMEOUT_S = 20.0  # wall seconds to wait for the first log row before arming
# While flying, MAVSDK's callback thread needs the GIL for every telemetry message (thousands a
# second at high speed-up); with CPython's default 5 ms switch interval a busy asyncio thread (log
# writer, display) makes it wait up to 5 ms per message and MAVSDK's bounded callback queue
# overflows ("Dropping subscription callbacks").  A 0.5 ms interval bounds that wait.
GIL_SWITCH_INTERVAL_S = 0.0005
# SIGHUP: a lost terminal (SSH), as SIGTERM
SIGNALS = (
    signal.SIGINT,
    signal.SIGTERM,
    signal.SIGHUP,
)


def auto_rate_hz(speedup: float) -> float:
    """Position/attitude rate to request (Hz of vehicle time): 50 Hz, lowered for a sped-up vehicle
    so that each stream stays under ``WALL_CALLBACKS_PER_STREAM`` callbacks per wall-clock second
    (MAVSDK delivers every message through one bounded callback queue that a Python consumer must
    keep up with), never below 30 Hz.  At speed-up 20: 30 Hz, i.e. 600 position + 600 attitude
    callbacks per second."""
    return max(MIN_RATE_HZ, min(RATE_HZ, WALL_CALLBACKS_PER_STREAM / max(speedup, 1e-9)))


@dataclass
class FlyOptions:
    """Command-line options of ``fly-mission`` (see ``mission.cli.fly``)."""

    connect: str | None = None
    speedup: float | None = None
    out: Path = Path("flights")
    localize: bool = True
    rss_source: str = "sim"
    link_timeout_s: float = 30.0  # also the wait for a first autopilot
    land_timeout_s: float = 600.0
    connect_timeout_s: float = 60.0  # waiting for a healthy position and home once connected
    rate_hz: float | None = None  # None: auto_rate_hz(speed-up)
    verbose: bool = False


@dataclass
class Plugins:
    """The MAVSDK plugins of the connected autopilot."""

    telemetry: Any
    action: Any
    mission_raw: Any
    param: Any
    direct: Any


def wall_clock_notice(duration_s: float, speedup: float, hint: bool = True) -> str:
    """How long a flight of ``duration_s`` vehicle seconds takes on the wall clock, with a hint (no
    vehicle seconds: the one plan figure is the budget's, with the autopilot's own speeds,
    ``budget.start_budget``)."""
    wall = duration_s / speedup
    text = f"estimated flight: about {_fmt_wall(wall)} of wall-clock time at speed-up {speedup:g}"
    if hint and speedup < 20 and wall > 60:
        text += f" (add --speedup 20 for about {_fmt_wall(duration_s / 20)})"
    return text


def _fmt_wall(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


def new_context(spec, opts: FlyOptions, extension=None) -> FlightContext:
    """The context of one flight of ``spec`` (an ``extension`` flies its own part of it first)."""
    speedup = float(opts.speedup or spec.vehicle.speedup or 1.0)
    url = opts.connect or spec.vehicle.connection
    flown = extension.spec if extension is not None else spec
    ctx = FlightContext(
        spec=flown,
        opts=opts,
        speedup=speedup,
        url=url,
        full_spec=spec,
        extension=extension,
        status=FlightStatus(mission_name=flown.name, budget_s=flown.time_budget_s),
        tel=Telemetry(rate_hint=speedup if not url else 1.0),
        phases=MonotonicPhases(),
        live=LiveEstimates(update_s=extension.update_s if extension is not None else 5.0),
    )
    return ctx


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def fly(spec, opts: FlyOptions, extension=None) -> int:
    """Run one flight to the end (blocking); returns the exit code.  Until the flight's own handlers
    are installed (and after they are removed), SIGTERM and SIGHUP are a Ctrl-C: exit 130, no
    traceback."""
    ctx = new_context(spec, opts, extension)

    async def main() -> int:
        ctx.live.start_worker()  # before connecting: the worker imports the localizer meanwhile
        try:
            return await run(ctx)
        finally:
            ctx.live.stop_worker()

    old = {sig: signal.signal(sig, _interrupt) for sig in SIGNALS[1:]}
    try:
        return asyncio.run(main())
    except KeyboardInterrupt:
        # interrupted: the process ends with 130, not by a second signal at exit
        ignore_terminal_signals()
        raise
    finally:
        # a flight started and its outcome is decided: a late Ctrl-C during the
        if ctx.source is not None:
            # exit (threads joined) must not end the process by the signal
            ignore_terminal_signals()
        # refused before anything started
        elif signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
            for sig, handler in old.items():
                signal.signal(sig, handler)


# ----------------------------------------------------------------- the flight's order
async def run(ctx: FlightContext) -> int:
    """Check, start the built-in vehicle if no connection is given, fly; signals abort (RTL once
    airborne)."""
    spec = ctx.spec
    check_options(ctx.opts)  # options: before anything starts
    # fence and budget: refuse before connecting or uploading anything
    report = assert_flyable(spec)
    ctx.source, ctx.truth = make_source(spec, ctx.opts.rss_source)
    signals = LoopSignals(
        asyncio.get_running_loop(), SIGNALS, functools.partial(tasks.on_signal, ctx)
    ).install()
    try:
        url = ctx.url
        if not url:
            port = free_udp_port()
            lat, lon, alt = spec.field.origin.to_geodetic(np.asarray(spec.home_enu, dtype=float))
            ctx.vehicle_proc = spawn_vehicle(
                port,
                ctx.speedup,
                (float(lat), float(lon), float(alt)),
                spec.kinematics(),
                spec.source.seed,
                ctx.opts.verbose,
            )
            url = f"udpin://127.0.0.1:{port}"
            ctx.event(
                "vehicle",
                f"simulated vehicle started (pid {ctx.vehicle_proc.pid}), {url}, "
                f"speed-up {ctx.speedup:g}",
            )
        ctx.event("duration", wall_clock_notice(report.duration_s, ctx.speedup, hint=not ctx.url))
        switch = sys.getswitchinterval()
        sys.setswitchinterval(min(switch, GIL_SWITCH_INTERVAL_S))
        try:
            code = await fly_sdk(ctx, url, report)
        finally:
            sys.setswitchinterval(switch)
    finally:
        signals.remove()  # back to fly()'s: a later signal is a Ctrl-C (exit 130)
        stop_vehicle(ctx.vehicle_proc)
    if ctx.opts.localize:  # after the flight: a Ctrl-C now is a plain interrupt (exit 130)
        print_result(ctx)
    return code


def make_source(spec, rss_source: str):
    """The RSS source (a receiver, or the simulated one with its true transmitter) and the truth
    record."""
    kind, arg = parse_source(rss_source)
    if kind != "sim":
        return make_receiver(kind, arg), None
    s = spec.source
    rng = np.random.default_rng(s.seed)  # the RSS noise
    tx = spec.transmitter()  # seed N's transmitter, where rfsl simulate puts it
    info = {
        "model": s.model,
        "model_params": s.model_params,
        "seed": s.seed,
        "tx_enu": [float(v) for v in tx],
        "tx_resolution": "tx=spec.transmitter(seed) (rfsl simulate's draw); noise: "
        "default_rng(seed)",
    }
    src = SimSource(
        spec.propagation_model(), tx, rng, s.noise_db, s.sample_period_s, spec.field.origin, info
    )
    return src, {"x_m": float(tx[0]), "y_m": float(tx[1]), "z_m": float(tx[2])}


async def connect(ctx: FlightContext, sdk, url: str):
    """The first autopilot on ``url`` within ``--link-timeout`` (FlightError with one line
    otherwise)."""
    ctx.status.stage = "waiting for autopilot"
    try:
        await sdk.add_any_connection(url)
    except Exception as e:  # MavsdkConnectionError: bad address, port in use, no such device
        raise FlightError(f"cannot open {url}: {e}", EXIT_LINK) from None
    t = ctx.opts.link_timeout_s
    system = await race(
        ctx, sdk.first_autopilot(timeout_s=t), timeout=t + 5.0, what=f"an autopilot on {url}"
    )
    if system is None:
        seen = ctx.sdklog.new_messages()
        why = f" (MAVSDK: {seen[-1]})" if seen else ""
        raise FlightError(f"no autopilot on {url} within {t:g} s{why}", EXIT_LINK)
    ap = await system.autopilot_type()
    ctx.autopilot = Autopilot.ARDUPILOT if ap == SdkAutopilot.ARDUPILOT else Autopilot.PX4
    ctx.builtin_vehicle = await is_builtin_vehicle(system)
    ctx.event(
        "connect", f"autopilot {ap.name}{' (built-in vehicle)' * ctx.builtin_vehicle} on {url}"
    )
    return system, ap.name


async def is_builtin_vehicle(system, tries: int = 10) -> bool:
    """Whether the autopilot's AUTOPILOT_VERSION names this project's built-in vehicle
    (``BUILTIN_PRODUCT``); False when it never answers within ``tries`` x 0.2 s."""

    info = InfoAsync(system)
    for _ in range(tries):
        try:
            p = await info.get_product()
        except Exception:  # InfoError: not received yet
            await asyncio.sleep(0.2)
            continue
        return (p.vendor_id, p.product_id) == BUILTIN_PRODUCT
    return False


async def fly_sdk(ctx: FlightContext, url: str, report) -> int:
    """Connect, then every coroutine of the flight under one task group; the log closed on every
    path."""
    code, status, error = EXIT_OK, "completed", None
    with SdkLog(ctx.opts.verbose) as ctx.sdklog, Display(ctx.status) as ctx.display:
        async with Mavsdk(
            Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        ) as sdk:
            system, ap_name = await connect(ctx, sdk, url)
            p = Plugins(
                TelemetryAsync(system),
                ActionAsync(system),
                MissionRawAsync(system),
                ParamAsync(system),
                MavlinkDirectAsync(system),
            )
            async with text_link(sdk) as texts, asyncio.TaskGroup() as tg:
                tasks.start_telemetry(ctx, tg, p.telemetry, p.mission_raw, p.direct, texts)
                tasks.spawn(ctx, tg, gcs_heartbeats(ctx, p.direct, ctx.speedup), "heartbeat")
                live_task = None
                try:
                    items = await prepare(ctx, p)
                    await open_log(ctx, url, ap_name, report, len(items))
                    tasks.spawn(ctx, tg, tasks.logger(ctx), "log writer")
                    tasks.spawn(
                        ctx,
                        tg,
                        watch_budget(ctx, ctx.budget, p.mission_raw, p.action),
                        "budget watch",
                    )
                    live_task = tasks.spawn(
                        ctx, tg, estimates.live_estimates(ctx), "live estimates"
                    )
                    code, status = await fly_mission(ctx, tg, p)
                except FlightError as e:
                    code, status = e.code, f"failed: {e}"
                    if ctx.rows is None:
                        error = e
                    else:
                        ctx.event("error", str(e), warn=True)
                        await safe_return(ctx, p.action)
                # a bug must not leave the vehicle without a plan, nor lose the log
                except Exception as e:
                    code, status = EXIT_FAILED, f"failed: {type(e).__name__}: {e}"
                    ctx.event("error", status, warn=True)
                    await safe_return(ctx, p.action)
                finally:
                    try:
                        status = await close(ctx, status, p.param, live_task)
                    finally:  # the task group waits for its tasks: none may outlive the close
                        for t in ctx.tasks:
                            t.cancel()
    if error is not None:
        raise error
    if code == EXIT_OK and ctx.abort.is_set():  # a signal after the landing: flown, but stop here
        code = EXIT_ABORTED
        status = f"aborted ({ctx.abort_reason}) after the landing"
    if ctx.status.log_error and code != EXIT_LINK:
        code, status = EXIT_LOG, log_status(ctx, status)
    if ctx.log_path is not None:
        with contextlib.suppress(OSError):  # a lost terminal (SIGHUP)
            print(f"log: {ctx.log_path}", flush=True)
    if code != EXIT_OK:
        raise FlightError(status.removeprefix("failed: "), code)
    return code


async def prepare(ctx: FlightContext, p: Plugins):
    """Health and home, the raw items, stream rates, the autopilot's speeds and the budget plan, the
    upload."""
    spec, opts = ctx.spec, ctx.opts
    ctx.status.stage = "waiting for position and home"
    await race(
        ctx,
        tasks.healthy(p.telemetry),
        timeout=opts.connect_timeout_s,
        what="a healthy position and home",
    )
    ctx.home = await p.telemetry.home()
    check_home(ctx, ctx.home)
    n_wp = len(spec.waypoints_enu())
    ctx.status.n_waypoints, ctx.status.waypoint_offset = n_wp, ctx.autopilot.waypoint_offset
    ctx.rate_requested = opts.rate_hz or auto_rate_hz(ctx.speedup)
    for name in ("set_rate_position", "set_rate_attitude_euler"):
        try:
            await getattr(p.telemetry, name)(ctx.rate_requested)
        except Exception as e:  # an autopilot may refuse: we log at whatever rate comes
            ctx.event("rate", f"{name}({ctx.rate_requested:g}) refused: {e}", warn=True)
    with contextlib.suppress(Exception):
        await p.telemetry.set_rate_landed_state(5.0)
    v_ret = await apply_speeds(ctx, p.param, ctx.ardupilot)  # restored after the flight
    ctx.budget = start_budget(
        ctx, v_ret, await vertical_speeds(ctx, p.param, ctx.ardupilot), ctx.ardupilot
    )
    if ctx.extension is not None:  # its own checks, now that the autopilot's plan is known (exit 2)
        ctx.extension.check(ctx)
    items = build_items(
        spec,
        (ctx.home.latitude_deg, ctx.home.longitude_deg, ctx.home.absolute_altitude_m),
        ctx.ardupilot,
        ctx.extension.hold_s(ctx) if ctx.extension is not None else 0.0,
    )
    ctx.phases.configure(
        ctx.status.waypoint_offset, len(items) - 1, final_phase(spec.return_behaviour)
    )
    ctx.status.stage = "uploading"
    await upload_with_retries(ctx, p.mission_raw, items)
    ctx.event("upload", f"mission uploaded: {len(items)} raw items ({n_wp} waypoints)")
    ctx.abort_before_takeoff()
    return items


def check_home(ctx: FlightContext, home) -> None:
    """One warning when the vehicle's home is far from the mission's (it takes off from its own)."""
    o = ctx.spec.field.origin
    enu = o.to_enu(home.latitude_deg, home.longitude_deg, home.absolute_altitude_m)
    d = float(np.hypot(enu[0] - ctx.spec.home_enu[0], enu[1] - ctx.spec.home_enu[1]))
    if d > 30.0:
        ctx.event(
            "home",
            f"vehicle home is {d:.0f} m from the mission's home; take-off from there",
            warn=True,
        )


async def open_log(ctx: FlightContext, url: str, ap_name: str, report, n_items: int) -> None:
    """A new flight folder, the writer with its sidecar (``status: flying``), the first row before
    arming."""
    spec = ctx.spec
    ctx.log_path = new_flight_dir(ctx.opts.out, spec.name) / "flight.csv"
    trajectory = (
        ctx.extension.trajectory_meta()
        if ctx.extension is not None
        else ctx.full_spec.trajectory_meta()
    )
    meta = make_meta(
        spec.field.origin,
        ctx.source.meta(),
        ctx.truth,
        mission=spec.name,
        mission_file=str(spec.path) if spec.path else None,
        trajectory=trajectory,
        connection=url,
        autopilot=ap_name,
        speedup_requested=ctx.speedup,
        telemetry_rate_requested_hz=ctx.rate_requested,
        status="flying",
        planned_duration_s=float(report.duration_s),
    )
    meta["live_estimate"] = estimates.log_meta(ctx)
    writer = FlightLogWriter(
        ctx.log_path, meta, extra_columns=PHASE_COLUMNS + ctx.source.extra_columns
    )
    ctx.rows = RowLogger(writer, ctx.source, ctx.tel, ctx.phases, spec.field.origin, ctx.status)
    ctx.rows.on_error = functools.partial(tasks.log_failed, ctx)
    ctx.event("log", f"logging to {ctx.log_path}")
    await ctx.source.start(ctx.tel.clock.now)
    ctx.status.stage = "waiting for the first log row"
    end = asyncio.get_running_loop().time() + FIRST_ROW_TIMEOUT_S
    # log on the ground before arming
    while not writer.rows and asyncio.get_running_loop().time() < end:
        ctx.abort_before_takeoff()
        ctx.rows.write()
        await asyncio.sleep(0.05)


async def fly_mission(ctx: FlightContext, tg: asyncio.TaskGroup, p: Plugins) -> tuple[int, str]:
    """Arm, start, the extension's coroutine beside the mission, then the return and landing."""
    ext = None
    if ctx.extension is not None:
        ext = tasks.spawn(ctx, tg, ctx.extension.fly(ctx, p.action, p.mission_raw), "extension")
    try:
        return await _arm_and_fly(ctx, p.action, p.mission_raw)
    finally:
        if ext is not None:
            ext.cancel()
            await asyncio.gather(ext, return_exceptions=True)


async def _arm_and_fly(ctx: FlightContext, action, mission_raw) -> tuple[int, str]:
    ctx.status.stage = "arming"
    for attempt in range(10):  # ArduPilot says "armable" before its EKF uses GPS: retry for 20 s
        ctx.abort_before_takeoff()
        try:
            await action.arm()
            break
        except ActionError as e:
            if attempt == 9:
                raise FlightError(f"arming refused: {e}") from None
            await asyncio.sleep(2.0)
    await wait_any(ctx.armed_seen, timeout=3.0)  # "armed" (the telemetry) before "mission started"
    ctx.status.t_start = ctx.tel.clock.now()
    await start_mission(ctx, action, mission_raw)
    ctx.event("start", "mission started")
    ev = await wait_any(ctx.mission_done, ctx.landed_disarmed, ctx.abort, ctx.link_dead)
    if ev is ctx.link_dead:
        return EXIT_LINK, "link lost"
    if ev is ctx.abort and not ctx.st.was_in_air:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(action.disarm(), 5.0)
        return _abort_code(ctx), f"aborted ({ctx.abort_reason}) before take-off: disarmed"
    await return_and_land(ctx, action, commanded=ev is ctx.abort)
    if ctx.abort.is_set():
        return _abort_code(ctx), f"aborted ({ctx.abort_reason}), {_return_outcome(ctx)}"
    if ctx.link_dead.is_set():
        return EXIT_LINK, "link lost"
    return EXIT_OK, "completed" if ctx.landed_disarmed.is_set() else "landing not confirmed"


def _abort_code(ctx: FlightContext) -> int:
    """A flight brought home by its own watch (``budget.stalled``) failed: 3; a signal
    interrupted it: 130."""
    return EXIT_LINK if ctx.abort_reason in (TAKEOFF_STALLED, OVERDUE) else EXIT_ABORTED


async def start_mission(ctx: FlightContext, action, mission_raw) -> None:
    """``start_mission``, retried: a loaded link (PX4 SITL at 10x on two busy cores) timed it out,
    and PX4 disarms an armed vehicle that does not take off within seconds (re-armed then)."""
    for attempt in range(3):
        ctx.abort_before_takeoff()
        try:
            await mission_raw.start_mission()
            return
        except MissionRawError as e:
            why = getattr(getattr(e, "result", None), "name", None) or type(e).__name__
            if attempt == 2:
                raise FlightError(f"mission start refused: {why}") from None
            ctx.event("start", f"mission start failed ({why}); retrying", warn=True)
            if not ctx.st.armed:
                with contextlib.suppress(Exception):
                    await action.arm()


def _return_outcome(ctx: FlightContext) -> str:
    """How a commanded return ended, as measured: landed, left in flight (a second signal), or
    unknown."""
    if ctx.landed_disarmed.is_set():
        return "returned to launch"
    if ctx.left_flying:
        return f"vehicle left in flight at {ctx.where()}"
    if ctx.link_dead.is_set():
        return "return commanded, then the link was lost: vehicle state unknown"
    return "return commanded, landing not confirmed"


async def safe_return(ctx: FlightContext, action) -> None:
    if ctx.st.in_air and not ctx.link_dead.is_set():
        await return_and_land(ctx, action)


async def return_and_land(ctx: FlightContext, action, commanded: bool = True) -> None:
    """Command RTL (if asked or still flying without a return), then wait for landed and
    disarmed."""
    if commanded:
        ctx.phases.on_return(ctx.tel.clock.now())
        for _ in range(5):
            try:
                await asyncio.wait_for(action.return_to_launch(), 5.0)
                ctx.event("rtl", "return to launch commanded")
                break
            except Exception as e:  # keep trying: the vehicle must not be left without a plan
                ctx.event("rtl", f"return to launch refused ({e}); retrying", warn=True)
                await asyncio.sleep(1.0)
    ev = await wait_any(ctx.landed_disarmed, ctx.link_dead, timeout=ctx.opts.land_timeout_s)
    if ev is ctx.landed_disarmed:
        await settle_texts(ctx, ctx.speedup)  # the autopilot's last texts before this line
        ctx.event("landed", "landed and disarmed")
    elif ev is None:
        ctx.event(
            "landed", f"landing not confirmed within {ctx.opts.land_timeout_s:g} s", warn=True
        )
    await asyncio.sleep(0.3)  # let the last telemetry after touchdown reach the log


async def close(ctx: FlightContext, status: str, param, live_task: asyncio.Task | None) -> str:
    """Live estimates and the extension's record, last rows, the coroutines cancelled, autopilot
    speeds restored, the log closed with its summary, budget and what is known of the vehicle;
    returns the final status (naming the autopilot parameters left changed, if any)."""
    if live_task is not None:
        live_task.cancel()
        await asyncio.gather(live_task, return_exceptions=True)
    await estimates.close_estimates(ctx)
    if ctx.rows is not None and ctx.extension is not None:
        key, record = ctx.extension.record(ctx)
        ctx.rows.writer.meta[key] = record
    if ctx.rows is not None:
        with contextlib.suppress(Exception):
            ctx.rows.write(final=True)
    for t in ctx.tasks:
        t.cancel()
    await asyncio.gather(*ctx.tasks, return_exceptions=True)
    await restore_speeds(ctx, param)
    # not restored (the vehicle may still fly on them)
    if ctx.restore_params and ctx.link_dead.is_set():
        left = ", ".join(f"{k} (was {v:g})" for k, v in ctx.restore_params.items())
        ctx.event("params", f"autopilot parameters left changed: {left}", warn=True)
        status += f"; parameters left changed: {', '.join(ctx.restore_params)}"
    if ctx.rows is None:
        return status
    await ctx.source.stop()
    for line in ctx.texts.summary():  # the autopilot's repeated texts, folded on screen
        ctx.say(line)
    summary = ctx.tel.summary()
    sdk = ctx.sdklog  # None: --verbose (MAVSDK prints its own log, nothing counted)
    summary["mavsdk_dropped_callbacks"] = sdk.dropped if sdk is not None and sdk.installed else None
    if ctx.budget is not None:
        summary["budget"] = close_budget(ctx, ctx.budget)
    w = ctx.rows.writer
    status = log_status(ctx, status)
    last = ctx.tel.clock.last_measured()
    try:
        w.close(
            status=status,
            events=ctx.st.events,
            link_lost=any(e["kind"] == "link" for e in ctx.st.events),
            speedup=summary["speedup_measured"] or ctx.speedup,
            vehicle_state=ctx.vehicle_state(),
            last_telemetry_vehicle_s=round(last, 3) if np.isfinite(last) else None,
            params_left_changed=dict(ctx.restore_params) if ctx.link_dead.is_set() else {},
            **summary,
        )
    except OSError as e:  # the sidecar itself could not be written (a full disk)
        ctx.status.log_error = ctx.status.log_error or e.strerror or type(e).__name__
        ctx.event(
            "log", f"sidecar not written ({e.strerror or e}): it may still say flying", warn=True
        )
    ctx.display.message(f"log closed: {ctx.log_path} ({w.rows} rows, {status})")
    return status


def log_status(ctx: FlightContext, status: str) -> str:
    """The end status, saying so when the log is incomplete."""
    why = ctx.status.log_error
    return status if not why or "log incomplete" in status else f"{status}; log incomplete ({why})"


# ----------------------------------------------------------------- after landing
def print_result(ctx: FlightContext) -> None:
    """The last lines of the run: the extension's (the in-flight final estimate) or ``localize``'s
    answer."""
    if ctx.extension is not None:
        print("\n".join(ctx.extension.result_lines(ctx)), flush=True)
        return
    try:
        # lazy (noqa) on purpose: a localizer that cannot load must not stop the flight's last lines
        from mission.localize.api import localize_log  # noqa: PLC0415
        from mission.localize.render import Shown  # noqa: PLC0415
    except ImportError as e:
        print(
            f"localizer not available ({e}); run `localize {ctx.log_path}` later", file=sys.stderr
        )
        return
    try:
        est = localize_log(ctx.log_path)
    except InputError as e:
        print(f"localizer refused the log: {e}", file=sys.stderr)
        return
    lines = Shown.of(est, ctx.truth).lines()
    print("\n".join(lines), flush=True)  # the last lines of the run, each within 80 columns
