"""The asyncio flight runner on MAVSDK v4: connect, check, upload, arm, fly, log RSS, return, land.

Why this shape: one asyncio task per concern (position, attitude, vehicle state, mission progress, the log
writer, the watchdog/display), so a slow or silent part (a stalled receiver, a lost link) never blocks the
others, and every exit path (end of mission, Ctrl-C/SIGTERM, link loss, an exception) goes through one
``finally`` that commands return-to-launch if the vehicle is still flying, waits for the landing (bounded)
and closes the log.  The log is appended and fsynced at least twice a second, so a crash or a kill leaves a
readable log up to the last half second.  Times are the vehicle's clock (``time_boot_ms``).

MAVSDK v4 API used (native binding, ``mavsdk.asyncio``): ``Mavsdk(Configuration.create_with_component_type(
ComponentType.GROUND_STATION))`` as an async context manager, ``add_any_connection``, ``first_autopilot``;
``TelemetryAsync`` (health, home, attitude_euler, armed, landed_state, set_rate_*), ``ActionAsync`` (arm,
return_to_launch), ``MissionRawAsync`` (upload_mission, start_mission, subscribe_mission_progress,
download_mission) and ``MavlinkDirectAsync`` (GLOBAL_POSITION_INT with its ``time_boot_ms``, which the
Telemetry plugin's position lacks).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime as _dt
import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.flight.progress import Display, FlightStatus
from mission.flight.telemetry import Telemetry

LINK_LOST_AFTER_S = 3.0
RATE_HZ, MIN_RATE_HZ = 50.0, 30.0  # position/attitude rate requested (vehicle time); the floor
WALL_CALLBACKS_PER_STREAM = 600.0  # at most this many per wall-clock second per stream (sped-up vehicles)


def auto_rate_hz(speedup: float) -> float:
    """Position/attitude rate to request (Hz of vehicle time): 50 Hz, lowered for a sped-up vehicle so that
    each stream stays under ``WALL_CALLBACKS_PER_STREAM`` callbacks per wall-clock second (MAVSDK delivers
    every message through one bounded callback queue that a Python consumer must keep up with), never
    below 30 Hz.  At speed-up 20: 30 Hz, i.e. 600 position + 600 attitude callbacks per second."""
    return max(MIN_RATE_HZ, min(RATE_HZ, WALL_CALLBACKS_PER_STREAM / max(speedup, 1e-9)))
EXIT_OK, EXIT_ABORTED, EXIT_LINK = 0, 130, 3


@dataclass
class FlyOptions:
    """Command-line options of ``fly-mission`` (see ``mission.cli.fly``)."""

    connect: str | None = None
    speedup: float | None = None
    out: Path = Path("flights")
    localize: bool = True
    rss_source: str = "sim"
    link_timeout_s: float = 30.0
    land_timeout_s: float = 600.0
    connect_timeout_s: float = 60.0
    rate_hz: float | None = None  # None: auto_rate_hz(speed-up)
    verbose: bool = False


class FlightError(Exception):
    """A flight that could not be flown or finished (exit code attached)."""

    def __init__(self, message: str, code: int = 1) -> None:
        super().__init__(message)
        self.code = code


def new_flight_dir(out: Path, name: str) -> Path:
    """A new, never-reused folder ``out/<name>_<UTC timestamp>[_k]`` for one flight."""
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    out.mkdir(parents=True, exist_ok=True)
    for k in range(1000):
        d = out / (f"{name}_{stamp}" + (f"_{k}" if k else ""))
        try:
            d.mkdir()
            return d
        except FileExistsError:
            continue
    raise FlightError(f"cannot create a new flight folder under {out}")


def wall_clock_notice(duration_s: float, speedup: float) -> str:
    """How long a flight of ``duration_s`` vehicle seconds takes on the wall clock, with a hint."""
    wall = duration_s / speedup
    text = (
        f"estimated flight {duration_s / 60:.1f} min of vehicle time: about {_fmt_wall(wall)} "
        f"of wall-clock time at speed-up {speedup:g}"
    )
    if speedup < 20 and wall > 60:
        text += f" (add --speedup 20 for about {_fmt_wall(duration_s / 20)})"
    return text


def _fmt_wall(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


def free_udp_port() -> int:
    """A UDP port that is free on 127.0.0.1 now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def spawn_vehicle(
    port: int,
    speedup: float,
    home: tuple[float, float, float],
    kin,
    seed: int,
    verbose: bool = False,
) -> subprocess.Popen:
    """Start the simulated vehicle (``python -m sitl.vehicle``) sending to 127.0.0.1:``port``.

    ``kin`` is the mission's full ``Kinematics`` (cruise speed, acceleration, climb rate, corner exponent,
    yaw rate, ...), passed as JSON so that the flown time matches the pre-flight budget check.
    """
    cmd = [
        sys.executable,
        "-m",
        "sitl.vehicle",
        "--port",
        str(port),
        "--speedup",
        f"{speedup:g}",
        "--home",
        f"{home[0]:.9f},{home[1]:.9f},{home[2]:.3f}",
        "--kinematics",
        json.dumps(dataclasses.asdict(kin)),
        "--seed",
        str(seed),
    ] + (["-v"] if verbose else [])
    return subprocess.Popen(
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=None if verbose else subprocess.DEVNULL,
        start_new_session=True,
    )


def configure_mavsdk_logging(verbose: bool) -> bool:
    """Keep MAVSDK's Info/Debug chatter off the terminal (warnings and errors still print); ``verbose``
    leaves MAVSDK's own logging untouched (everything).  Returns True when a filter was installed."""
    if verbose:
        return False
    from mavsdk import LogLevel, log_subscribe

    def _filter(level, message, file, line) -> bool:
        return level < LogLevel.WARN  # True: swallowed; False: MAVSDK prints it as usual

    log_subscribe(_filter)
    return True


# While flying, MAVSDK's callback thread needs the GIL for every telemetry message (thousands a second at
# high speed-up); with CPython's default 5 ms switch interval a busy asyncio thread (log writer, display)
# makes it wait up to 5 ms per message and MAVSDK's bounded callback queue overflows ("Dropping
# subscription callbacks").  A 0.5 ms interval bounds that wait.
GIL_SWITCH_INTERVAL_S = 0.0005


def _q(a: np.ndarray, digits: int) -> np.ndarray:
    """Round exactly as the log writes (decimal text) and read back, so logged == used values."""
    return np.char.mod(f"%.{digits}f", np.asarray(a, dtype=float)).astype(float)


@dataclass
class _State:
    armed: bool = False
    was_armed: bool = False
    in_air: bool = False
    was_in_air: bool = False
    landed_state: str = "UNKNOWN"
    progress: tuple[int, int] = (0, 0)
    events: list[dict] = field(default_factory=list)


class Runner:
    """One flight of ``spec`` with ``opts``; ``await run()`` returns the process exit code."""

    def __init__(self, spec, opts: FlyOptions) -> None:
        self.spec, self.opts = spec, opts
        self.speedup = float(opts.speedup or spec.vehicle.speedup or 1.0)
        self.url = opts.connect or spec.vehicle.connection
        self.status = FlightStatus(mission_name=spec.name, budget_s=spec.time_budget_s)
        self.st = _State()
        self.tel = Telemetry(rate_hint=self.speedup if not self.url else 1.0)
        self.abort = asyncio.Event()
        self.abort_reason = ""
        self.link_dead = asyncio.Event()
        self.landed_disarmed = asyncio.Event()
        self.mission_done = asyncio.Event()
        self.link_lost = False
        self.writer = None
        self.t_ref: float | None = None
        self.vehicle_proc: subprocess.Popen | None = None
        self.display: Display | None = None
        self.log_path: Path | None = None
        self._last_flush = 0.0
        self._source_warned = False

    # ----------------------------------------------------------------- events and messages
    def event(self, kind: str, text: str, warn: bool = False) -> None:
        t = self.tel.clock.now()
        self.st.events.append(
            {
                "t_vehicle_s": None if not np.isfinite(t) else round(t, 3),
                "kind": kind,
                "text": text,
                "wall": time.time(),
            }
        )
        if warn:
            self.status.warnings.append(text)
        if self.display is not None:
            self.display.message(("WARNING: " if warn else "") + text, "yellow" if warn else "")
        else:
            print(("WARNING: " if warn else "") + text, file=sys.stderr, flush=True)

    def _on_signal(self, name: str) -> None:
        if self.abort.is_set():
            self.event("signal", f"{name} again: stop waiting for the landing")
            self.link_dead.set()
            return
        self.abort_reason = name
        self.event("abort", f"{name} received: returning to launch")
        self.abort.set()

    # ----------------------------------------------------------------- tasks
    async def _positions(self, direct) -> None:
        async for m in direct.subscribe_message("GLOBAL_POSITION_INT"):
            f = json.loads(m.fields_json)
            self.tel.add_position(
                f["time_boot_ms"] / 1000.0,
                f["lat"] * 1e-7,
                f["lon"] * 1e-7,
                f["alt"] / 1000.0,
                f["relative_alt"] / 1000.0,
            )
            self.status.rel_alt = f["relative_alt"] / 1000.0

    async def _attitudes(self, telemetry) -> None:
        async for a in telemetry.subscribe_attitude_euler():
            self.tel.add_attitude(
                a.timestamp_us / 1e6, np.deg2rad(a.roll_deg), np.deg2rad(a.pitch_deg), np.deg2rad(a.yaw_deg)
            )

    async def _armed(self, telemetry) -> None:
        async for armed in telemetry.subscribe_armed():
            if armed != self.st.armed:
                self.event("armed" if armed else "disarmed", "armed" if armed else "disarmed")
            self.st.armed = armed
            self.st.was_armed |= armed
            self._check_landed()

    async def _landed(self, telemetry) -> None:
        async for ls in telemetry.subscribe_landed_state():
            name = getattr(ls, "name", str(ls))
            if name != self.st.landed_state:
                self.st.landed_state = name
                self.status.phase = name.lower().replace("_", " ")
            self.st.in_air = name in ("IN_AIR", "TAKING_OFF", "LANDING")
            self.st.was_in_air |= self.st.in_air
            self._check_landed()

    def _check_landed(self) -> None:
        if (
            self.st.was_armed
            and self.st.was_in_air
            and not self.st.armed
            and self.st.landed_state == "ON_GROUND"
        ):
            self.landed_disarmed.set()

    async def _progress(self, mission_raw) -> None:
        async for p in mission_raw.subscribe_mission_progress():
            self.st.progress = (p.current, p.total)
            self.status.item, self.status.items = p.current, p.total
            if p.total and p.current >= p.total - 1 and self.st.was_in_air:
                if not self.mission_done.is_set():
                    self.event("mission", f"last mission item ({p.current}) active: returning")
                self.mission_done.set()

    async def _status_texts(self, telemetry) -> None:
        async for s in telemetry.subscribe_status_text():
            self.event("statustext", f"autopilot: {s.text}")

    async def _logger(self) -> None:
        while True:
            await asyncio.sleep(0.2)
            self.write_rows()

    async def _watchdog(self) -> None:
        while True:
            await asyncio.sleep(0.25)
            silent = self.tel.clock.silent_for()
            if self.tel.n_pos and silent > LINK_LOST_AFTER_S and not self.link_lost:
                self.link_lost = True
                self.event(
                    "link", f"MAVLink link lost (no telemetry for {silent:.0f} s); still logging", warn=True
                )
            elif self.link_lost and silent < 1.0:
                self.link_lost = False
                self.event("link", "MAVLink link restored", warn=True)
            if self.link_lost and silent > self.opts.link_timeout_s:
                self.event("link", f"no telemetry for {silent:.0f} s: giving up the flight", warn=True)
                self.link_dead.set()
            src = self.source
            if src is not None and not src.needs_model and self.st.was_armed and not self.link_lost:
                stalled = src.stalled_for()
                if stalled > 2.0 and not self._source_warned:
                    self._source_warned = True
                    self.event(
                        "rss", f"RSS source {src.kind} delivered nothing for {stalled:.0f} s", warn=True
                    )
                elif stalled < 1.0 and self._source_warned:
                    self._source_warned = False
                    self.event("rss", f"RSS source {src.kind} delivering again", warn=True)
            self.status.t_now = self.tel.clock.now() if self.tel.n_pos else 0.0
            if self.st.was_armed and (self.status.t_start is None or not np.isfinite(self.status.t_start)):
                self.status.t_start = self.status.t_now if self.tel.n_pos else None
            if self.display is not None:
                self.display.refresh()

    # ----------------------------------------------------------------- logging
    def write_rows(self, final: bool = False) -> None:
        """Drain the source up to the telemetry's coverage, interpolate, (simulate), append, flush."""
        if self.writer is None or self.source is None or not self.tel.n_pos or not self.tel.n_att:
            return
        t_until = self.tel.covered_until
        if final and not self.source.needs_model:
            t_until = np.inf  # receivers: keep every sample; telemetry is held at the ends
        t, vals, extra = self.source.drain(t_until)
        if len(t):
            if self.t_ref is None:
                self.t_ref = float(t[0])
                self.writer.meta["t0_vehicle_s"] = self.t_ref
            pos, att = self.tel.at(t)
            att_deg = np.rad2deg(att)
            cols = {
                "t_s": _q(t - self.t_ref, 4),
                "lat_deg": _q(pos[:, 0], 9),
                "lon_deg": _q(pos[:, 1], 9),
                "alt_m": _q(pos[:, 2], 3),
                "rel_alt_m": _q(pos[:, 3], 3),
                "roll_deg": _q(att_deg[:, 0], 3),
                "pitch_deg": _q(att_deg[:, 1], 3),
                "yaw_deg": _q(att_deg[:, 2], 3),
            }
            if vals is None:
                vals = self.source.evaluate(
                    cols["lat_deg"],
                    cols["lon_deg"],
                    cols["alt_m"],
                    np.stack([cols["roll_deg"], cols["pitch_deg"], cols["yaw_deg"]], -1),
                )
            cols["rss_dbm"] = np.asarray(vals, dtype=float)
            cols.update(extra)
            self.writer.append(cols)
            self.status.rows = self.writer.rows
            self.status.last_rss = float(cols["rss_dbm"][-1])
            i = int(np.argmax(cols["rss_dbm"]))
            if cols["rss_dbm"][i] > self.status.best_rss:
                self.status.best_rss = float(cols["rss_dbm"][i])
                enu = self.spec.field.origin.to_enu(cols["lat_deg"][i], cols["lon_deg"][i], cols["alt_m"][i])
                self.status.best_xy = (float(enu[0]), float(enu[1]))
        now = time.monotonic()
        if final or now - self._last_flush >= 0.5:
            self.writer.flush()
            self._last_flush = now

    # ----------------------------------------------------------------- setup
    def _make_source(self):
        from mission.flight.sources import SimSource, make_receiver, parse_source

        kind, arg = parse_source(self.opts.rss_source)
        if kind != "sim":
            return make_receiver(kind, arg), None
        s = self.spec.source
        rng = np.random.default_rng(s.seed)
        tx = self.spec.resolve_tx(rng)
        model = self.spec.propagation_model()
        info = {
            "model": s.model,
            "model_params": s.model_params,
            "seed": s.seed,
            "tx_enu": [float(v) for v in tx],
            "tx_resolution": "rng=default_rng(seed); tx=spec.resolve_tx(rng)",
        }
        src = SimSource(model, tx, rng, s.noise_db, s.sample_period_s, self.spec.field.origin, info)
        return src, {"x_m": float(tx[0]), "y_m": float(tx[1]), "z_m": float(tx[2])}

    async def _wait(self, *events: asyncio.Event, timeout: float | None = None) -> asyncio.Event | None:
        """Wait until one of ``events`` is set (returns it) or the timeout passes (None)."""
        waits = {asyncio.ensure_future(e.wait()): e for e in events}
        try:
            done, _ = await asyncio.wait(waits, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for w in waits:
                w.cancel()
        for e in events:
            if e.is_set():
                return e
        return None

    # ----------------------------------------------------------------- main
    async def run(self) -> int:
        from mission.trajectory.checks import assert_flyable

        spec = self.spec
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self._on_signal, sig.name)
        self.source = None
        try:
            report = assert_flyable(spec)  # fence and budget: refuse before connecting or uploading anything
            url = self.url
            if not url:
                port = free_udp_port()
                o = spec.field.origin
                lat, lon, alt = o.to_geodetic(np.asarray(spec.home_enu, dtype=float))
                self.vehicle_proc = spawn_vehicle(
                    port,
                    self.speedup,
                    (float(lat), float(lon), float(alt)),
                    spec.kinematics(),
                    spec.source.seed,
                    self.opts.verbose,
                )
                url = f"udpin://127.0.0.1:{port}"
                self.event(
                    "vehicle",
                    f"simulated vehicle started (pid {self.vehicle_proc.pid}), {url}, "
                    f"speed-up {self.speedup:g}",
                )
                self.event("duration", wall_clock_notice(report.duration_s, self.speedup))
            return await self._fly(url, report)
        finally:
            for sig in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(sig)
            if self.vehicle_proc is not None:
                self.vehicle_proc.terminate()
                try:
                    self.vehicle_proc.wait(5)
                except subprocess.TimeoutExpired:
                    self.vehicle_proc.kill()

    async def _fly(self, url: str, report) -> int:
        from mavsdk.asyncio import Autopilot, ComponentType, Configuration, Mavsdk

        opts = self.opts
        filtered = configure_mavsdk_logging(opts.verbose)
        switch = sys.getswitchinterval()
        sys.setswitchinterval(min(switch, GIL_SWITCH_INTERVAL_S))
        try:
            return await self._fly_sdk(url, report, Mavsdk, ComponentType, Configuration, Autopilot)
        finally:
            sys.setswitchinterval(switch)
            if filtered:
                from mavsdk import log_unsubscribe

                log_unsubscribe()

    async def _fly_sdk(self, url, report, Mavsdk, ComponentType, Configuration, Autopilot) -> int:
        from mavsdk.asyncio.plugins.action import ActionAsync
        from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
        from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
        from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

        from mission.flight.plan import build_items, to_mavsdk
        from mission.flightlog import FlightLogWriter, make_meta

        spec, opts = self.spec, self.opts
        async with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
            await sdk.add_any_connection(url)
            self.status.phase = "waiting for autopilot"
            system = await self._race(sdk.first_autopilot(timeout_s=opts.connect_timeout_s))
            if system is None:
                raise FlightError(f"no autopilot on {url} within {opts.connect_timeout_s:g} s", EXIT_LINK)
            ap = await system.autopilot_type()
            ardupilot = ap == Autopilot.ARDUPILOT
            self.event("connect", f"autopilot {ap.name} on {url}")
            telemetry, action, mission_raw = (
                TelemetryAsync(system),
                ActionAsync(system),
                MissionRawAsync(system),
            )
            direct = MavlinkDirectAsync(system)
            self.status.phase = "waiting for position and home"
            await self._race(
                self._healthy(telemetry), timeout=opts.connect_timeout_s, what="a healthy position and home"
            )
            home = await telemetry.home()
            self._check_home(home)
            items = build_items(
                spec, home.latitude_deg, home.longitude_deg, home.absolute_altitude_m, ardupilot
            )
            self.status.n_waypoints = len(spec.waypoints_enu())
            self.status.waypoint_offset = 3 if ardupilot else 2
            rate = opts.rate_hz or auto_rate_hz(self.speedup)
            for name in ("set_rate_position", "set_rate_attitude_euler"):
                try:
                    await getattr(telemetry, name)(rate)
                except Exception as e:  # an autopilot may refuse: we log at whatever rate comes
                    self.event("rate", f"{name}({rate:g}) refused: {e}", warn=True)
            with contextlib.suppress(Exception):
                await telemetry.set_rate_landed_state(5.0)
            self.status.phase = "uploading"
            from mavsdk.plugins.mission_raw import MissionRawError

            for attempt in range(3):  # a busy link (high speed-up) can time out one transfer
                try:
                    await mission_raw.upload_mission(to_mavsdk(items))
                    break
                except MissionRawError as e:
                    if attempt == 2:
                        raise FlightError(f"mission upload failed: {e.result.name}", EXIT_LINK) from None
                    self.event("upload", f"mission upload failed ({e.result.name}); retrying", warn=True)
            self.event(
                "upload", f"mission uploaded: {len(items)} raw items ({self.status.n_waypoints} waypoints)"
            )
            if self.abort.is_set():
                raise FlightError("aborted before take-off", EXIT_ABORTED)

            self.source, truth = self._make_source()
            flight_dir = new_flight_dir(opts.out, spec.name)
            self.log_path = flight_dir / "flight.csv"
            meta = make_meta(
                spec.field.origin,
                self.source.meta(),
                truth,
                mission=spec.name,
                mission_file=str(spec.path) if spec.path else None,
                connection=url,
                autopilot=ap.name,
                speedup=self.speedup,
                status="flying",
                planned_duration_s=float(report.duration_s),
            )
            self.writer = FlightLogWriter(self.log_path, meta, extra_columns=self.source.extra_columns)
            self.event("log", f"logging to {self.log_path}")
            await self.source.start(self.tel.clock.now)
            tasks = [
                asyncio.create_task(c)
                for c in (
                    self._positions(direct),
                    self._attitudes(telemetry),
                    self._armed(telemetry),
                    self._landed(telemetry),
                    self._progress(mission_raw),
                    self._status_texts(telemetry),
                    self._logger(),
                    self._watchdog(),
                )
            ]
            code, status = EXIT_OK, "completed"
            with Display(self.status) as self.display:
                try:
                    code, status = await self._mission(action, mission_raw, telemetry)
                except FlightError as e:
                    code, status = e.code, f"failed: {e}"
                    self.event("error", str(e), warn=True)
                    if self.st.in_air and not self.link_dead.is_set():
                        await self._return_and_land(action)
                finally:
                    with contextlib.suppress(Exception):
                        self.write_rows(final=True)
                    for t in tasks:
                        t.cancel()
                    await asyncio.gather(*tasks, return_exceptions=True)
                    await self.source.stop()
                    self.writer.close(
                        status=status,
                        events=self.st.events,
                        link_lost=any(e["kind"] == "link" for e in self.st.events),
                    )
                    self.display.message(f"log closed: {self.log_path} ({self.writer.rows} rows, {status})")
            self.display = None
        print(f"log: {self.log_path}", flush=True)
        if code == EXIT_OK and opts.localize:
            self._localize()
        return code

    async def _race(self, coro, timeout: float | None = None, what: str = ""):
        """Await ``coro`` unless an abort comes first (then FlightError) or ``timeout`` passes."""
        task = asyncio.ensure_future(coro)
        ab = asyncio.ensure_future(self.abort.wait())
        done, _ = await asyncio.wait({task, ab}, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
        ab.cancel()
        if task in done:
            return task.result()
        task.cancel()
        if self.abort.is_set():
            raise FlightError(
                f"aborted ({self.abort_reason}) before take-off: nothing was flown", EXIT_ABORTED
            )
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
            self.event(
                "home", f"vehicle home is {d:.0f} m from the mission's home; take-off from there", warn=True
            )

    async def _mission(self, action, mission_raw, telemetry) -> tuple[int, str]:
        from mavsdk.plugins.action import ActionError

        self.status.phase = "arming"
        for attempt in range(10):
            try:
                await action.arm()
                break
            except ActionError as e:
                if attempt == 9 or self.abort.is_set():
                    raise FlightError(f"arming refused: {e}") from None
                await asyncio.sleep(2.0)
        self.status.t_start = self.tel.clock.now()
        await mission_raw.start_mission()
        self.event("start", "mission started")
        self.status.phase = "mission"
        ev = await self._wait(self.mission_done, self.landed_disarmed, self.abort, self.link_dead)
        if ev is self.link_dead:
            return EXIT_LINK, "link lost"
        await self._return_and_land(action, commanded=ev is self.abort)
        if self.abort.is_set():
            return EXIT_ABORTED, f"aborted ({self.abort_reason}), returned to launch"
        if self.link_dead.is_set():
            return EXIT_LINK, "link lost"
        return EXIT_OK, "completed" if self.landed_disarmed.is_set() else "landing not confirmed"

    async def _return_and_land(self, action, commanded: bool = True) -> None:
        """Command RTL (if asked or still flying without a return), then wait for landed and disarmed."""
        if commanded:
            self.status.phase = "return to launch"
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
            self.event("landed", "landed and disarmed")
            self.status.phase = "landed"
        elif ev is None:
            self.event("landed", f"landing not confirmed within {self.opts.land_timeout_s:g} s", warn=True)
        # let the last telemetry after touchdown reach the log
        await asyncio.sleep(0.3)

    def _localize(self) -> None:
        try:
            from mission.localize.api import localize_log
        except ImportError as e:
            print(
                f"localizer not available ({e}); run `rfsl localize {self.log_path}` later", file=sys.stderr
            )
            return
        try:
            est = localize_log(self.log_path)
        except InputError as e:
            print(f"localizer refused the log: {e}", file=sys.stderr)
            return
        print(
            f"estimate: x={est.x_m:.1f} m, y={est.y_m:.1f} m (lat {est.lat_deg:.7f}, lon {est.lon_deg:.7f}) "
            f"[{est.method}]",
            flush=True,
        )


def fly(spec, opts: FlyOptions) -> int:
    """Run one flight to the end (blocking); returns the exit code."""
    if os.name == "nt":  # pragma: no cover - signal handlers need a Unix loop
        raise FlightError("fly-mission needs a Unix-like OS (signal handling)")
    return asyncio.run(Runner(spec, opts).run())
