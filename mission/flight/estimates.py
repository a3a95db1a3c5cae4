"""The live estimates of every flight: a series from the log as written, the 3-minute fast one, the
final one.

Why here: every flight has them (adaptive or not).  ``live_estimates`` asks for an estimate every
``update_s`` vehicle seconds from the log as written (``live.estimate_file_at`` in a worker process,
so the loop and MAVSDK's callback thread never wait on numpy), the fast estimate 3 minutes after
take-off and the final one (every mission and adaptive row, up to the switch to the return).  The
series goes into the sidecar (``estimates``, rewritten through the writer after each, so an abort
keeps it).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import os
import time
from dataclasses import dataclass, field

import numpy as np

from mission.flight import live
from mission.flight.context import FlightContext
from mission.flight.vehicle_process import terminal_signals_ignored
from mission.flightlog import FLOWN_PHASES
from mission.localize.render import Shown
from mission.threads import pool_context


@dataclass
class LiveEstimates:
    """The worker process and the series of one flight; ``wall_s``: the wall-clock seconds each
    estimate took (an adaptive flight sizes its waits by them)."""

    update_s: float = 5.0
    estimates: list[dict] = field(default_factory=list)
    fast: dict | None = None
    final: dict | None = None
    wall_s: list[float] = field(default_factory=list)
    pool: concurrent.futures.ProcessPoolExecutor | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)

    def latency_s(self, last: int = 10) -> float | None:
        """The longest wall-clock time of the last ``last`` estimates (None before the first)."""
        return max(self.wall_s[-last:]) if self.wall_s else None

    def start_worker(self) -> None:
        """spawn: a fresh interpreter (no MAVSDK threads forked), started and warmed up before
        connecting. It starts with the terminal's signals ignored (inherited), so a Ctrl-C during
        its start-up is no ``KeyboardInterrupt`` traceback either; so does multiprocessing's
        resource tracker (which ignores SIGINT and SIGTERM itself, not SIGHUP)."""
        # the worker (this first submit) and multiprocessing's resource tracker
        with terminal_signals_ignored():
            self.pool = concurrent.futures.ProcessPoolExecutor(
                1,
                mp_context=pool_context(),
                initializer=live.lower_priority,
                initargs=(os.getpid(),),
            )
            self.pool.submit(live.warm_up)

    def stop_worker(self) -> None:
        """Stop the worker now: an estimate still running must not hold up the exit (where a Ctrl-C
        would end the process by the signal instead of exit 130).  Then wait (at most 5 s) for
        the executor's manager thread, which closes its wake-up pipe once it sees the worker gone:
        Python 3.11's exit hook writes to that pipe unlocked, and an exit during the close printed
        "Exception ignored ... OSError: [Errno 9] Bad file descriptor" after a one-line error (a
        CI run of "connecting to nothing")."""
        if self.pool is not None:
            # the executor's own record (private)
            procs = list(getattr(self.pool, "_processes", None) or {})
            procs = [self.pool._processes[k] for k in procs]
            manager = getattr(self.pool, "_executor_manager_thread", None)
            self.pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.kill()
            if manager is not None:
                manager.join(timeout=5.0)


def log_meta(ctx: FlightContext) -> dict:
    """The sidecar's ``live_estimate`` record (how to reproduce the series)."""
    return {
        "method": live.DEFAULT_LIVE,
        "level": live.LEVEL,
        "update_s": ctx.live.update_s,
        "reproduce": "localize LOG --at T (T: the entry's t_s, log time)",
    }


def log_time(ctx: FlightContext) -> float:
    """Log time (``t_s``) up to which every row is written and on disk."""
    ctx.rows.write()
    ctx.rows.flush()
    return ctx.tel.covered_until - ctx.rows.t_ref if ctx.rows.t_ref is not None else -np.inf


async def until_logged(ctx: FlightContext, t_log: float, timeout: float = 5.0) -> None:
    end = asyncio.get_running_loop().time() + timeout
    while log_time(ctx) < t_log and asyncio.get_running_loop().time() < end:
        await asyncio.sleep(0.05)


async def estimate(ctx: FlightContext, t_log: float | None = None) -> dict | None:
    """The live estimate from the rows up to ``t_log`` (None: all written so far), in the worker
    process."""
    async with ctx.live.lock:
        t = log_time(ctx) if t_log is None else t_log
        t0 = time.monotonic()
        fut = ctx.live.pool.submit(live.estimate_file_at, str(ctx.log_path), float(t))
        d = await asyncio.wrap_future(fut)
        ctx.live.wall_s.append(time.monotonic() - t0)
        return d


def record(ctx: FlightContext, d: dict, what: str = "") -> None:
    """Append ``d`` to the flight's series (the status line, the sidecar; an event when ``what``
    names it)."""
    lv = ctx.live
    lv.estimates.append(d)
    text = Shown.of_entry(d, ctx.truth).line()
    ctx.status.estimate = text
    # the series survives an abort or a crash of the ground station
    with contextlib.suppress(OSError):
        ctx.rows.writer.update_meta(estimates=lv.estimates)
    if what:
        ctx.event("estimate", f"{what} estimate, t={d['t_s']:.0f} s: {text}")


async def live_estimates(ctx: FlightContext) -> None:
    """Task: the periodic series, the fast estimate at 3 minutes, the final one once the mission
    ends."""
    lv = ctx.live
    while True:
        await asyncio.sleep(0.2)
        # the period runs from the last entry of the series, whoever made it (a round's planning)
        last = lv.estimates[-1]["t_s"] if lv.estimates else -np.inf
        t0 = ctx.status.t_start
        if ctx.rows.t_ref is None or t0 is None or not np.isfinite(t0) or not ctx.st.was_in_air:
            continue
        t_arm = t0 - ctx.rows.t_ref
        if lv.fast is None and ctx.tel.clock.now() - t0 >= live.FAST_ESTIMATE_S:
            await until_logged(ctx, t_arm + live.FAST_ESTIMATE_S)
            lv.fast = await estimate(ctx, t_arm + live.FAST_ESTIMATE_S) or {}
            if lv.fast:
                ctx.rows.writer.meta["fast_estimate"] = lv.fast
                record(ctx, lv.fast, "fast (3 min)")
        due = ctx.tel.clock.now() - ctx.rows.t_ref - last >= lv.update_s
        if lv.final is None and ctx.phases.current in FLOWN_PHASES and due:
            d = await estimate(ctx)
            if d is not None:
                record(ctx, d)
        if ctx.mission_done.is_set() or ctx.abort.is_set():
            await final_estimate(ctx)  # once; the loop goes on for a fast estimate still due


async def final_estimate(ctx: FlightContext) -> None:
    """The in-flight final estimate: every mission and adaptive row, up to the switch to the
    return."""
    lv = ctx.live
    if lv.final is not None or ctx.rows is None or ctx.rows.t_ref is None:
        return
    ph = np.asarray(ctx.phases.phase)
    flown = np.flatnonzero(np.isin(ph, FLOWN_PHASES))
    if not len(flown):
        return
    k = int(flown[-1]) + 1
    t_end = (ctx.phases.t[k] if k < len(ph) else ctx.tel.covered_until) - ctx.rows.t_ref
    await until_logged(ctx, t_end)
    lv.final = await estimate(ctx, min(t_end, log_time(ctx))) or {}
    if lv.final:
        ctx.rows.writer.meta["final_estimate"] = lv.final
        record(ctx, lv.final, "final")


async def close_estimates(ctx: FlightContext) -> None:
    """At the close: the final estimate if still due (bounded; not after a second Ctrl-C, which
    asked to stop now), the series into the sidecar, the worker stopped."""
    if ctx.rows is not None and not ctx.left_flying:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(final_estimate(ctx), 30.0)
    if ctx.rows is not None:
        ctx.rows.writer.meta.update(estimates=ctx.live.estimates)
    ctx.live.stop_worker()
