"""The estimate a flight has at time T: what ``fly-mission`` shows in flight and ``localize --at T``
reproduces.

Why one function for both: the in-flight estimate is computed from the log file itself (the rows
written up to T, rounded as written), with the same sample selection and method choice as
``localize`` (``localize_log`` with no method), so a finished log, real or simulated, gives back
exactly the time series the flight recorded, and the flight's last estimate is the one ``localize``
prints after landing, not a second opinion beside it.  On an adaptive flight that choice is
``methods.ADAPTIVE_METHOD`` (the self-calibrating grid), whose posterior the rounds plan on.  In
flight it runs in a separate process (``estimate_file_at``), never in the asyncio loop's thread, so
neither the loop nor MAVSDK's callback thread waits on it.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
import warnings

import numpy as np

from mission.errors import InputError
from mission.flight.vehicle_process import die_with_parent, ignore_terminal_signals
from mission.localize.methods import ADAPTIVE_ANSWER, ADAPTIVE_METHOD, JUDGED_PICK
from mission.localize.render import SERIES_LEVEL

DEFAULT_LIVE = (
    "default"  # recorded in the sidecar: the live estimates used ``localize``'s own choice
)
FAST_ESTIMATE_S = 180.0  # the AFAR rules' fast estimate: 3 minutes after take-off
LEVEL = SERIES_LEVEL  # the level of an entry's region area (one home: the renderer's)


def recorded_method(meta: dict) -> str | None:
    """The method a flown log's live estimates used (None: ``localize``'s own choice, or no record).

    Why: logs flown before the live estimate followed ``localize`` recorded ``selfcal``; ``localize
    --at T`` on them must still give back what that flight showed."""
    m = (meta.get("live_estimate") or {}).get("method")
    return None if m in (None, DEFAULT_LIVE) else str(m)


def log_at(log, t_s: float, source: str | None = None):
    """The rows of ``log`` with ``t_s`` <= T (a ``FlightLog``); T before the first row is an
    ``InputError``."""
    if not math.isfinite(t_s):
        raise InputError(f"time must be finite, got {t_s}", source=source, field="--at")
    t = np.asarray(log["t_s"], dtype=float)
    keep = t <= t_s + 1e-9
    if not keep.any():
        raise InputError(
            f"no rows at or before t = {t_s:g} s (the log starts at {t[0]:g} s)",
            source=source,
            field="--at",
        )
    return log.select(keep)


def estimate_at(log, t_s: float | None = None, method: str | None = None):
    """The ``localize_log`` estimate from the rows up to ``t_s`` (None: all rows); ``method`` None:
    its choice."""
    # the worker process's imports (noqa): the flight process never loads the localizer
    from mission.localize.api import localize_log  # noqa: PLC0415

    part = log if t_s is None else log_at(log, t_s, str(log.path) if log.path else None)
    return localize_log(part, method=method)


def summary(est, t_s: float) -> dict:
    """One entry of the sidecar's ``estimates`` series: t, x, y, 90 % region area (and error when
    known; on an adaptive flight's answer, the live method's own 90 % area, ``live_area_m2``)."""
    reg = est.region(LEVEL)
    d = {
        "t_s": round(float(t_s), 3),
        "x_m": round(est.x_m, 2),
        "y_m": round(est.y_m, 2),
        "area_m2": None if reg is None else round(float(reg.area_m2), 1),
        "method": est.method,
    }
    if est.error_m is not None:
        d["error_m"] = round(float(est.error_m), 2)
    if est.method == ADAPTIVE_ANSWER and (own := est.components.get(ADAPTIVE_METHOD)) is not None:
        # an adaptive flight's answer prints its regions at masses calibrated on adaptive flights;
        # the planner stops on the live method's own region, as the benchmark's simulator does
        # (adaptive.simflight), so the rounds flown do not depend on how the answer is printed
        reg = own.region(LEVEL)
        d["live_area_m2"] = None if reg is None else round(float(reg.area_m2), 1)
    if (pick := est.extras.get(JUDGED_PICK)) is not None:  # where the planner goes first
        d[JUDGED_PICK] = [round(float(v), 1) for v in pick]
    if getattr(est, "posterior", None) is not None and est.posterior.grid is not None:
        # the worker process's imports (noqa): the flight process never loads the localizer
        from mission.adaptive.planner import posterior_candidates  # noqa: PLC0415

        d["candidates"] = [
            [round(v, 1 if i < 2 else 3) for i, v in enumerate(c)]
            for c in posterior_candidates(est.posterior)
        ]
    return d


def estimate_file_at(path: str, t_s: float) -> dict | None:
    """``summary`` of the estimate from the log file's rows up to ``t_s`` (None: too few samples
    yet).

    Runs in a worker process: reads the file as far as it is written (a cut last line is
    dropped)."""
    # the worker process's imports (noqa): the flight process never loads the localizer
    from mission.flightlog import read_flight_log  # noqa: PLC0415

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            log = read_flight_log(path)
            return summary(estimate_at(log, t_s), t_s)
        except (InputError, ValueError, FloatingPointError):
            return None


def lower_priority(parent_pid: int | None = None) -> None:
    """Worker initializer: the estimate yields the CPU to the flight (telemetry, log writer, a local
    SITL).

    The worker also dies with ``fly-mission``: a ``kill -9`` of the flight must not leave it holding
    the flight's pipes (the kernel's parent-death signal, and a parent-pid poll where that is not
    available); it ignores the terminal's signals (a Ctrl-C reaches the whole process group): the
    flight stops it."""
    ignore_terminal_signals()
    with contextlib.suppress(OSError):
        os.nice(5)
    die_with_parent()
    if parent_pid is not None:

        def watch() -> None:
            while os.getppid() == parent_pid:
                time.sleep(1.0)
            os._exit(0)

        threading.Thread(target=watch, daemon=True).start()


def warm_up() -> None:
    """Import the localizer in a fresh worker process (seconds) before the first estimate is
    needed."""
    # the worker process's imports (noqa): the flight process never loads the localizer
    import mission.flightlog  # noqa: F401, PLC0415
    import mission.localize.api  # noqa: F401, PLC0415
