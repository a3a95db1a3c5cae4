"""``fly-mission``'s runner with live estimates (every flight) and the adaptive finish (``--adaptive``).

Why a subclass of ``flight.runner.Runner``: the order of a flight (check, connect, upload, arm, fly, return,
land, close) and its safety paths stay in one place; this adds two asyncio tasks.  ``_live`` asks for an
estimate every ``update_s`` vehicle seconds from the log as written (``live.estimate_file_at`` in a worker
process, so the loop and MAVSDK's callback thread never wait on numpy), the 3-minute fast estimate and the
final one; the series goes into the sidecar (``estimates``, rewritten after each, so an abort keeps it).
``_adapt`` extends the uploaded mission round by round: ``lead_s`` before the current round (or the survey)
ends it plans the next one from the live estimate (``planner.plan_round``: fence, altitude limits, budget
with the return reserved), and re-uploads the whole mission with the new round before the final RTL.  Items
already flown keep their indices, so the current item stays valid (``set_current_mission_item`` re-asserts
it: PX4 and the built-in vehicle reset it on upload); a round that comes too late means the vehicle is
already returning, which is safe.  MAVSDK v4 API: ``MissionRawAsync.upload_mission`` and
``set_current_mission_item`` (PX4 and ArduPilot alike, no guided mode needed).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import dataclasses
import multiprocessing
import os

import numpy as np

from mission.adaptive import live
from mission.flight.phases import PhaseTracker
from mission.flight.runner import Runner
from mission.flightlog import FLOWN_PHASES
from mission.localize.methods import ADAPTIVE_METHOD


class MonotonicPhases(PhaseTracker):
    """Mission progress never goes back in flight: a re-upload briefly reports item 0 before the current item is
    set again, which must not relabel rows as take-off."""

    def on_progress(self, t: float, raw_item: int) -> None:
        if self.landed_state == "ON_GROUND" or raw_item >= self.raw_item or self.returning:
            super().on_progress(t, raw_item)


class LiveRunner(Runner):
    """A flight with live estimates; with ``adaptive`` (an ``AdaptiveSpec``) the survey then adaptive rounds."""

    def __init__(self, spec, opts, adaptive=None) -> None:
        from mission.adaptive.planner import survey_spec

        self.full_spec, self.adaptive = spec, adaptive
        super().__init__(survey_spec(spec, adaptive.survey_s) if adaptive else spec, opts)
        self.phases = MonotonicPhases()
        self.update_s = adaptive.update_s if adaptive else 5.0
        self.estimates: list[dict] = []
        self.fast: dict | None = None
        self.final: dict | None = None
        self.rounds: list[dict] = []
        self.home = None
        self.planning = False  # the adaptive task needs the worker soon: no periodic estimate meanwhile
        # spawn: a fresh interpreter (no MAVSDK threads forked), started and warmed up before connecting
        self._pool = concurrent.futures.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                                                            initializer=live.lower_priority,
                                                            initargs=(os.getpid(),))
        self._pool.submit(live.warm_up)
        self._lock: asyncio.Lock | None = None
        self._live_task: asyncio.Task | None = None

    def _check_home(self, home) -> None:
        self.home = home
        super()._check_home(home)

    async def _prepare(self, telemetry, mission_raw, param, ardupilot: bool):
        """The base preparation, then the adaptive budget again with the autopilot's own return (known now):
        refused before take-off, exit 2, when it leaves no round."""
        items = await super()._prepare(telemetry, mission_raw, param, ardupilot)
        if self.adaptive:
            from mission.adaptive.feasibility import adaptive_violations
            from mission.adaptive.rounds import autopilot_return_extra_s
            from mission.flight.runner import FlightError

            extra = autopilot_return_extra_s(self, self.spec.waypoints_enu()[-1])
            if v := adaptive_violations(self.full_spec, self.adaptive, extra):
                raise FlightError(f"{self.full_spec.source_name}, field '{v[0][0]}': {v[0][1]}", 2)
        return items

    # ----------------------------------------------------------------- live estimates
    async def _open_log(self, url, ap_name, report, n_items) -> None:
        await super()._open_log(url, ap_name, report, n_items)
        meta = self.rows.writer.meta
        meta["trajectory"] = self.full_spec.trajectory_meta()
        if self.adaptive:
            meta["trajectory"]["adaptive"] = dataclasses.asdict(self.adaptive)
        meta["live_estimate"] = {"method": live.DEFAULT_LIVE, "level": live.LEVEL, "update_s": self.update_s,
                                 "reproduce": "localize LOG --at T (T: the entry's t_s, log time)"}
        self._lock = asyncio.Lock()
        self._live_task = asyncio.create_task(self._live())

    def _log_time(self) -> float:
        """Log time (``t_s``) up to which every row is written and on disk."""
        self.rows.write()
        self.rows.writer.flush()
        return self.tel.covered_until - self.rows.t_ref if self.rows.t_ref is not None else -np.inf

    async def _until_logged(self, t_log: float, timeout: float = 5.0) -> None:
        end = asyncio.get_running_loop().time() + timeout
        while self._log_time() < t_log and asyncio.get_running_loop().time() < end:
            await asyncio.sleep(0.05)

    async def estimate(self, t_log: float | None = None) -> dict | None:
        """The live estimate from the rows up to ``t_log`` (None: all written so far), in the worker process."""
        async with self._lock:
            t = self._log_time() if t_log is None else t_log
            fut = self._pool.submit(live.estimate_file_at, str(self.log_path), float(t))
            return await asyncio.wrap_future(fut)

    def _record(self, d: dict, what: str = "") -> None:
        self.estimates.append(d)
        self.status.estimate = live.describe(d, self.truth)
        w = self.rows.writer
        w.meta["estimates"] = self.estimates
        with contextlib.suppress(OSError):
            w._write_sidecar()  # the series survives an abort or a crash of the ground station
        if what:
            self.event("estimate", f"{what} estimate, t={d['t_s']:.0f} s: {live.describe(d, self.truth)}")

    async def _live(self) -> None:
        last = -np.inf
        while True:
            await asyncio.sleep(0.2)
            t0 = self.status.t_start
            if self.rows.t_ref is None or t0 is None or not np.isfinite(t0) or not self.st.was_in_air:
                continue
            t_arm = t0 - self.rows.t_ref
            if self.fast is None and self.tel.clock.now() - t0 >= live.FAST_ESTIMATE_S:
                await self._until_logged(t_arm + live.FAST_ESTIMATE_S)
                self.fast = await self.estimate(t_arm + live.FAST_ESTIMATE_S) or {}
                if self.fast:
                    self.rows.writer.meta["fast_estimate"] = self.fast
                    self._record(self.fast, "fast (3 min)")
            due = self.tel.clock.now() - self.rows.t_ref - last >= self.update_s
            if self.final is None and self.phases.current in FLOWN_PHASES and due and not self.planning:
                d = await self.estimate()
                if d is not None:
                    last = d["t_s"]
                    self._record(d)
            if self.mission_done.is_set() or self.abort.is_set():
                await self._final()  # once; the loop goes on for a fast estimate still due

    async def _final(self) -> None:
        """The in-flight final estimate: every mission and adaptive row, up to the switch to the return."""
        if self.final is not None or self.rows is None or self.rows.t_ref is None:
            return
        ph = np.asarray(self.phases.phase)
        flown = np.flatnonzero(np.isin(ph, FLOWN_PHASES))
        if not len(flown):
            return
        k = int(flown[-1]) + 1
        t_end = (self.phases.t[k] if k < len(ph) else self.tel.covered_until) - self.rows.t_ref
        await self._until_logged(t_end)
        self.final = await self.estimate(min(t_end, self._log_time())) or {}
        if self.final:
            self.rows.writer.meta["final_estimate"] = self.final
            self._record(self.final, "final")

    # ----------------------------------------------------------------- adaptive rounds
    async def _mission(self, action, mission_raw):
        task = asyncio.create_task(self._adapt(action, mission_raw)) if self.adaptive else None
        try:
            return await super()._mission(action, mission_raw)
        finally:
            if task is not None:
                task.cancel()
                await asyncio.gather(task, return_exceptions=True)

    async def _adapt(self, action, mission_raw) -> None:
        from mission.adaptive.rounds import adapt

        try:
            await adapt(self, action, mission_raw)
        except asyncio.CancelledError:
            raise
        except Exception as e:  # the survey's RTL stays uploaded: the vehicle returns by itself
            self.event("adaptive", f"adaptive part stopped ({type(e).__name__}: {e}); returning", warn=True)

    # ----------------------------------------------------------------- end
    async def _close(self, tasks, status, param) -> None:
        if self._live_task is not None:
            self._live_task.cancel()
            await asyncio.gather(self._live_task, return_exceptions=True)
        if self.rows is not None and self._lock is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._final(), 30.0)
            self.rows.writer.meta.update(estimates=self.estimates)
            if self.adaptive:
                from mission.adaptive.rounds import budget_report

                self.rows.writer.meta["adaptive"] = budget_report(self)
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        await super()._close(tasks, status, param)

    def _localize(self) -> None:
        if not self.adaptive:
            return super()._localize()
        if not self.final:
            print("no final estimate (too few samples)", flush=True)
            return
        print(f"estimate: {live.describe(self.final, self.truth)} [{ADAPTIVE_METHOD}, in flight]", flush=True)
        print(f"(t={self.final['t_s']:g} s: `localize LOG --at {self.final['t_s']:g}` gives it back)", flush=True)


def fly_live(spec, opts, adaptive=None) -> int:
    """Run one flight with live estimates (and the adaptive finish when ``adaptive`` is given)."""
    return asyncio.run(LiveRunner(spec, opts, adaptive).run())
