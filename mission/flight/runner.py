"""The asyncio flight runner on MAVSDK v4: connect, check, upload, arm, fly, log RSS, return, land.

Why this shape: one asyncio task per concern (position, attitude, vehicle state, mission progress, the log
writer, the watchdog/display), so a slow or silent part (a stalled receiver, a lost link) never blocks the
others, and every exit path (end of mission, Ctrl-C/SIGTERM, link loss, an exception) goes through one
``finally`` that commands return-to-launch if the vehicle is still flying, waits for the landing (bounded)
and closes the log.  Telemetry is subscribed right after connecting, so the log starts on the ground
before arming.  Options are checked (``preflight``) before anything starts.  Times are the vehicle's clock
(``time_boot_ms``); the sidecar records the measured speed-up and telemetry rates.

MAVSDK v4 API used (native binding, ``mavsdk.asyncio``): ``Mavsdk(Configuration.create_with_component_type(
ComponentType.GROUND_STATION))`` as an async context manager, ``add_any_connection``, ``first_autopilot``;
``TelemetryAsync`` (health, home, attitude_euler, armed, landed_state, set_rate_*), ``ActionAsync`` (arm,
disarm, return_to_launch), ``MissionRawAsync`` (upload_mission, start_mission, subscribe_mission_progress),
``ParamAsync`` (ArduPilot return settings) and ``MavlinkDirectAsync`` (GLOBAL_POSITION_INT with its
``time_boot_ms``, which the Telemetry plugin's position lacks).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.flight.budget import close_budget, start_budget, watch_budget
from mission.flight.heartbeat import gcs_heartbeats, settle_texts
from mission.flight.phases import PhaseTracker, final_phase
from mission.flight.progress import Display, FlightStatus
from mission.flight.speeds import apply_speeds, restore_speeds, vertical_speeds
from mission.flight.tasks import EXIT_ABORTED, EXIT_FAILED, EXIT_LINK, EXIT_OK, FlightError, FlightTasks
from mission.flight.telemetry import Telemetry
from mission.flight.vehicle_process import free_udp_port, spawn_vehicle, stop_vehicle

RATE_HZ, MIN_RATE_HZ = 50.0, 30.0  # position/attitude rate requested (vehicle time); the floor
WALL_CALLBACKS_PER_STREAM = 600.0  # at most this many per wall-clock second per stream (sped-up vehicles)
FIRST_ROW_TIMEOUT_S = 20.0  # wall seconds to wait for the first log row before arming
# While flying, MAVSDK's callback thread needs the GIL for every telemetry message (thousands a second at
# high speed-up); with CPython's default 5 ms switch interval a busy asyncio thread (log writer, display)
# makes it wait up to 5 ms per message and MAVSDK's bounded callback queue overflows ("Dropping
# subscription callbacks").  A 0.5 ms interval bounds that wait.
GIL_SWITCH_INTERVAL_S = 0.0005


def auto_rate_hz(speedup: float) -> float:
    """Position/attitude rate to request (Hz of vehicle time): 50 Hz, lowered for a sped-up vehicle so that
    each stream stays under ``WALL_CALLBACKS_PER_STREAM`` callbacks per wall-clock second (MAVSDK delivers
    every message through one bounded callback queue that a Python consumer must keep up with), never
    below 30 Hz.  At speed-up 20: 30 Hz, i.e. 600 position + 600 attitude callbacks per second."""
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


def wall_clock_notice(duration_s: float, speedup: float, hint: bool = True) -> str:
    """How long a flight of ``duration_s`` vehicle seconds takes on the wall clock, with a hint (no vehicle
    seconds: the one plan figure is the budget's, with the autopilot's own speeds, ``budget.start_budget``)."""
    wall = duration_s / speedup
    text = (
        f"estimated flight: about {_fmt_wall(wall)} of wall-clock time at speed-up {speedup:g}"
    )
    if hint and speedup < 20 and wall > 60:
        text += f" (add --speedup 20 for about {_fmt_wall(duration_s / 20)})"
    return text


def _fmt_wall(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


class Runner(FlightTasks):
    """One flight of ``spec`` with ``opts``; ``await run()`` returns the process exit code.

    The telemetry tasks, signals and the watchdog live in ``FlightTasks`` (``mission.flight.tasks``);
    this class holds the order of a flight: check, connect, upload, arm, fly, return, land, close.
    """

    def __init__(self, spec, opts: FlyOptions) -> None:
        self.spec, self.opts = spec, opts
        self.speedup = float(opts.speedup or spec.vehicle.speedup or 1.0)
        self.url = opts.connect or spec.vehicle.connection
        self.status = FlightStatus(mission_name=spec.name, budget_s=spec.time_budget_s)
        self.tel = Telemetry(rate_hint=self.speedup if not self.url else 1.0)
        self.phases = PhaseTracker()
        super().__init__()
        self.vehicle_proc: subprocess.Popen | None = None
        self.log_path: Path | None = None
        self.rows = None  # RowLogger once the log is open
        self.truth: dict | None = None
        self.restore_params: dict[str, int | float] = {}  # autopilot parameters to put back after the flight
        self.budget = None  # BudgetWatch once the plan is known

    # ----------------------------------------------------------------- main
    async def run(self) -> int:
        from mission.flight.preflight import check_options
        from mission.trajectory.checks import assert_flyable

        spec = self.spec
        check_options(self.opts)  # options: before anything starts
        report = assert_flyable(spec)  # fence and budget: refuse before connecting or uploading anything
        self.source, self.truth = self._make_source()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self._on_signal, sig.name)
        try:
            url = self.url
            if not url:
                port = free_udp_port()
                lat, lon, alt = spec.field.origin.to_geodetic(np.asarray(spec.home_enu, dtype=float))
                self.vehicle_proc = spawn_vehicle(
                    port, self.speedup, (float(lat), float(lon), float(alt)), spec.kinematics(),
                    spec.source.seed, self.opts.verbose,
                )
                url = f"udpin://127.0.0.1:{port}"
                self.event("vehicle", f"simulated vehicle started (pid {self.vehicle_proc.pid}), {url}, "
                           f"speed-up {self.speedup:g}")
            self.event("duration", wall_clock_notice(report.duration_s, self.speedup, hint=not self.url))
            switch = sys.getswitchinterval()
            sys.setswitchinterval(min(switch, GIL_SWITCH_INTERVAL_S))
            try:
                return await self._fly_sdk(url, report)
            finally:
                sys.setswitchinterval(switch)
        finally:
            for sig in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(sig)
            stop_vehicle(self.vehicle_proc)

    def _make_source(self):
        from mission.flight.sources import SimSource, make_receiver, parse_source

        kind, arg = parse_source(self.opts.rss_source)
        if kind != "sim":
            return make_receiver(kind, arg), None
        s = self.spec.source
        rng = np.random.default_rng(s.seed)  # the RSS noise
        tx = self.spec.transmitter()  # seed N's transmitter, where rfsl simulate puts it
        info = {"model": s.model, "model_params": s.model_params, "seed": s.seed, "tx_enu": [float(v) for v in tx],
                "tx_resolution": "tx=spec.transmitter(seed) (rfsl simulate's draw); noise: default_rng(seed)"}
        src = SimSource(self.spec.propagation_model(), tx, rng, s.noise_db, s.sample_period_s,
                        self.spec.field.origin, info)
        return src, {"x_m": float(tx[0]), "y_m": float(tx[1]), "z_m": float(tx[2])}

    async def _connect(self, sdk, url: str):
        """The first autopilot on ``url`` within ``--link-timeout`` (FlightError with one line otherwise)."""
        from mavsdk.asyncio import Autopilot

        self.status.stage = "waiting for autopilot"
        try:
            await sdk.add_any_connection(url)
        except Exception as e:  # MavsdkConnectionError: bad address, port in use, no such device
            raise FlightError(f"cannot open {url}: {e}", EXIT_LINK) from None
        t = self.opts.link_timeout_s
        system = await self._race(sdk.first_autopilot(timeout_s=t), timeout=t + 5.0, what=f"an autopilot on {url}")
        if system is None:
            seen = self.sdklog.new_messages()
            why = f" (MAVSDK: {seen[-1]})" if seen else ""
            raise FlightError(f"no autopilot on {url} within {t:g} s{why}", EXIT_LINK)
        ap = await system.autopilot_type()
        self.event("connect", f"autopilot {ap.name} on {url}")
        return system, ap == Autopilot.ARDUPILOT, ap.name

    async def _fly_sdk(self, url: str, report) -> int:
        from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
        from mavsdk.asyncio.plugins.action import ActionAsync
        from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
        from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
        from mavsdk.asyncio.plugins.param import ParamAsync
        from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

        from mission.flight.sdklog import SdkLog

        opts = self.opts
        code, status, tasks = EXIT_OK, "completed", []
        with SdkLog(opts.verbose) as self.sdklog, Display(self.status) as self.display:
            async with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
                system, ardupilot, ap_name = await self._connect(sdk, url)
                telemetry, action = TelemetryAsync(system), ActionAsync(system)
                mission_raw, param = MissionRawAsync(system), ParamAsync(system)
                direct = MavlinkDirectAsync(system)
                tasks = self.start_telemetry_tasks(telemetry, mission_raw, direct)
                tasks.append(asyncio.create_task(gcs_heartbeats(self, direct, self.speedup)))
                try:
                    items = await self._prepare(telemetry, mission_raw, param, ardupilot)
                    await self._open_log(url, ap_name, report, len(items))
                    tasks.append(asyncio.create_task(self._logger()))
                    tasks.append(asyncio.create_task(watch_budget(self, self.budget, mission_raw, action)))
                    code, status = await self._mission(action, mission_raw)
                except FlightError as e:
                    code, status = e.code, f"failed: {e}"
                    if self.rows is None:
                        raise
                    self.event("error", str(e), warn=True)
                    await self._safe_return(action)
                except Exception as e:  # a bug must not leave the vehicle without a plan, nor lose the log
                    code, status = EXIT_FAILED, f"failed: {type(e).__name__}: {e}"
                    self.event("error", status, warn=True)
                    await self._safe_return(action)
                finally:
                    await self._close(tasks, status, param)
        if self.log_path is not None:
            print(f"log: {self.log_path}", flush=True)
        if code == EXIT_OK and opts.localize:
            self._localize()
        elif code != EXIT_OK:
            raise FlightError(status.removeprefix("failed: "), code)
        return code

    async def _prepare(self, telemetry, mission_raw, param, ardupilot: bool):
        """Health and home, the raw items, stream rates, the autopilot's speeds and the budget plan, the upload."""
        from mission.flight.plan import UploadFailed, upload_items
        from mission.trajectory.items import build_items

        spec, opts = self.spec, self.opts
        self.status.stage = "waiting for position and home"
        await self._race(self._healthy(telemetry), timeout=opts.connect_timeout_s, what="a healthy position and home")
        home = await telemetry.home()
        self._check_home(home)
        self.home = home  # the mission's items are built about it (budget.act re-uploads them)
        items = build_items(spec, (home.latitude_deg, home.longitude_deg, home.absolute_altitude_m), ardupilot)
        n_wp = len(spec.waypoints_enu())
        self.status.n_waypoints, self.status.waypoint_offset = n_wp, 3 if ardupilot else 2
        self.phases.configure(self.status.waypoint_offset, len(items) - 1, final_phase(spec.return_behaviour))
        self.rate_requested = opts.rate_hz or auto_rate_hz(self.speedup)
        for name in ("set_rate_position", "set_rate_attitude_euler"):
            try:
                await getattr(telemetry, name)(self.rate_requested)
            except Exception as e:  # an autopilot may refuse: we log at whatever rate comes
                self.event("rate", f"{name}({self.rate_requested:g}) refused: {e}", warn=True)
        with contextlib.suppress(Exception):
            await telemetry.set_rate_landed_state(5.0)
        v_ret = await apply_speeds(self, param, ardupilot)  # restored after the flight
        self.budget = start_budget(self, v_ret, await vertical_speeds(self, param, ardupilot), ardupilot)
        self.status.stage = "uploading"
        try:  # a busy link (high speed-up) can time one transfer out: retried
            await upload_items(mission_raw, items, on_retry=lambda why: self.event(
                "upload", f"mission upload failed ({why}); retrying", warn=True))
        except UploadFailed as e:
            raise FlightError(str(e), EXIT_LINK) from None
        self.event("upload", f"mission uploaded: {len(items)} raw items ({n_wp} waypoints)")
        self._abort_before_takeoff()
        return items

    async def _open_log(self, url: str, ap_name: str, report, n_items: int) -> None:
        from mission.flight.logrows import RowLogger, new_flight_dir
        from mission.flightlog import PHASE_COLUMNS, FlightLogWriter, make_meta

        spec = self.spec
        self.log_path = new_flight_dir(self.opts.out, spec.name) / "flight.csv"
        meta = make_meta(
            spec.field.origin, self.source.meta(), self.truth, mission=spec.name,
            mission_file=str(spec.path) if spec.path else None, trajectory=spec.trajectory_meta(),
            connection=url, autopilot=ap_name,
            speedup_requested=self.speedup, telemetry_rate_requested_hz=self.rate_requested,
            status="flying", planned_duration_s=float(report.duration_s),
        )
        writer = FlightLogWriter(self.log_path, meta, extra_columns=PHASE_COLUMNS + self.source.extra_columns)
        self.rows = RowLogger(writer, self.source, self.tel, self.phases, spec.field.origin, self.status)
        self.event("log", f"logging to {self.log_path}")
        await self.source.start(self.tel.clock.now)
        self.status.stage = "waiting for the first log row"
        end = asyncio.get_running_loop().time() + FIRST_ROW_TIMEOUT_S
        while not writer.rows and asyncio.get_running_loop().time() < end:  # log on the ground before arming
            self._abort_before_takeoff()
            self.rows.write()
            await asyncio.sleep(0.05)

    async def _mission(self, action, mission_raw) -> tuple[int, str]:
        from mavsdk.plugins.action import ActionError

        self.status.stage = "arming"
        for attempt in range(10):  # ArduPilot says "armable" before its EKF uses GPS: retry for 20 s
            self._abort_before_takeoff()
            try:
                await action.arm()
                break
            except ActionError as e:
                if attempt == 9:
                    raise FlightError(f"arming refused: {e}") from None
                await asyncio.sleep(2.0)
        await self._wait(self.armed_seen, timeout=3.0)  # "armed" (the telemetry) before "mission started"
        self.status.t_start = self.tel.clock.now()
        await self._start_mission(action, mission_raw)
        self.event("start", "mission started")
        ev = await self._wait(self.mission_done, self.landed_disarmed, self.abort, self.link_dead)
        if ev is self.link_dead:
            return EXIT_LINK, "link lost"
        if ev is self.abort and not self.st.was_in_air:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(action.disarm(), 5.0)
            return EXIT_ABORTED, f"aborted ({self.abort_reason}) before take-off: disarmed"
        await self._return_and_land(action, commanded=ev is self.abort)
        if self.abort.is_set():
            return EXIT_ABORTED, f"aborted ({self.abort_reason}), returned to launch"
        if self.link_dead.is_set():
            return EXIT_LINK, "link lost"
        return EXIT_OK, "completed" if self.landed_disarmed.is_set() else "landing not confirmed"

    async def _start_mission(self, action, mission_raw) -> None:
        """``start_mission``, retried: a loaded link (PX4 SITL at 10x on two busy cores) timed it out, and PX4
        disarms an armed vehicle that does not take off within seconds (re-armed then)."""
        from mavsdk.plugins.mission_raw import MissionRawError

        for attempt in range(3):
            self._abort_before_takeoff()
            try:
                await mission_raw.start_mission()
                return
            except MissionRawError as e:
                why = getattr(e.result, "name", type(e).__name__)
                if attempt == 2:
                    raise FlightError(f"mission start refused: {why}") from None
                self.event("start", f"mission start failed ({why}); retrying", warn=True)
                if not self.st.armed:
                    with contextlib.suppress(Exception):
                        await action.arm()

    async def _safe_return(self, action) -> None:
        if self.st.in_air and not self.link_dead.is_set():
            await self._return_and_land(action)

    async def _return_and_land(self, action, commanded: bool = True) -> None:
        """Command RTL (if asked or still flying without a return), then wait for landed and disarmed."""
        if commanded:
            self.phases.on_return(self.tel.clock.now())
            for _ in range(5):
                try:
                    await asyncio.wait_for(action.return_to_launch(), 5.0)
                    self.event("rtl", "return to launch commanded")
                    break
                except Exception as e:  # keep trying: the vehicle must not be left without a plan
                    self.event("rtl", f"return to launch refused ({e}); retrying", warn=True)
                    await asyncio.sleep(1.0)
        ev = await self._wait(self.landed_disarmed, self.link_dead, timeout=self.opts.land_timeout_s)
        if ev is self.landed_disarmed:
            await settle_texts(self, self.speedup)  # the autopilot's last texts before this line
            self.event("landed", "landed and disarmed")
        elif ev is None:
            self.event("landed", f"landing not confirmed within {self.opts.land_timeout_s:g} s", warn=True)
        await asyncio.sleep(0.3)  # let the last telemetry after touchdown reach the log

    async def _close(self, tasks, status: str, param) -> None:
        """Last rows, tasks cancelled, autopilot speeds restored, the log closed with its summary and budget."""
        if self.rows is not None:
            with contextlib.suppress(Exception):
                self.rows.write(final=True)
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await restore_speeds(self, param)
        if self.rows is None:
            return
        await self.source.stop()
        for line in self.texts.summary():  # the autopilot's repeated texts, folded on screen
            self.say(line)
        summary = self.tel.summary()
        if self.budget is not None:
            summary["budget"] = close_budget(self, self.budget)
        w = self.rows.writer
        w.close(status=status, events=self.st.events, link_lost=any(e["kind"] == "link" for e in self.st.events),
                speedup=summary["speedup_measured"] or self.speedup, **summary)
        self.display.message(f"log closed: {self.log_path} ({w.rows} rows, {status})")

    def _localize(self) -> None:
        try:
            from mission.localize.api import localize_log
            from mission.localize.uncertainty import describe_region, outer_region
        except ImportError as e:
            print(f"localizer not available ({e}); run `localize {self.log_path}` later", file=sys.stderr)
            return
        try:
            est = localize_log(self.log_path)
        except InputError as e:
            print(f"localizer refused the log: {e}", file=sys.stderr)
            return
        model = est.extras.get("model_path")  # which network answered, when one did
        label = est.method + (f" {Path(model).name}" if model else "")
        lines = [f"estimate: x={est.x_m:.1f} m, y={est.y_m:.1f} m (lat {est.lat_deg:.7f}, lon {est.lon_deg:.7f})",
                 f"  method: {label}"]
        outer = outer_region(est.extras)
        lines.append(f"  {100 * outer['level']:.0f} % region: {describe_region(outer, short=True)}" if outer is not None
                     else "  region: none: no calibration applies to this flight (localize --json: notes)")
        if self.truth is not None:
            err = float(np.hypot(est.x_m - self.truth["x_m"], est.y_m - self.truth["y_m"]))
            lines.append(f"  error: {err:.1f} m (true transmitter at {self.truth['x_m']:.1f}, "
                         f"{self.truth['y_m']:.1f} m)")
        print("\n".join(lines), flush=True)  # the last lines of the run, each within 80 columns


def fly(spec, opts: FlyOptions) -> int:
    """Run one flight to the end (blocking); returns the exit code."""
    if os.name == "nt":  # pragma: no cover - signal handlers need a Unix loop
        raise FlightError("fly-mission needs a Unix-like OS (signal handling)")
    return asyncio.run(Runner(spec, opts).run())
