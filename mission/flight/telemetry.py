"""Time-stamped telemetry on the vehicle's clock, and interpolation of it to RSS sample times.

Why: RSS samples and telemetry arrive on different schedules; every logged RSS row carries the
position and attitude interpolated to *its* time stamp.  All times are the vehicle's
(``time_boot_ms``), not the wall clock, so that a sped-up simulated vehicle (or a SITL running
faster than real time) logs correctly.
"""

from __future__ import annotations

import itertools
import time
from collections import deque

import numpy as np


class Series:
    """An append-only time series of fixed-width float rows, kept in a bounded ring (the recent
    past)."""

    def __init__(self, width: int, keep: int = 20000) -> None:
        self.t: deque[float] = deque(maxlen=keep)
        self.v: deque[tuple[float, ...]] = deque(maxlen=keep)
        self.width = width

    def add(self, t: float, values: tuple[float, ...]) -> bool:
        """Append a sample; out-of-order or repeated times are dropped (returns False)."""
        if self.t and t <= self.t[-1]:
            return False
        self.t.append(t)
        self.v.append(values)
        return True

    @property
    def last_t(self) -> float:
        return self.t[-1] if self.t else -np.inf

    @property
    def first_t(self) -> float:
        return self.t[0] if self.t else np.inf

    def window(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Times (N,) and rows (N, width) of the samples with ``t0 < t <= t1`` still in the ring."""
        k = 0
        for tk in reversed(self.t):
            if tk <= t0:
                break
            k += 1
        t, v = self._tail(k)
        keep = t <= t1
        return t[keep], v[keep]

    def _tail(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The last ``k`` samples as arrays: times (k,) and rows (k, width)."""
        t = np.fromiter(itertools.islice(self.t, len(self.t) - k, None), float, k)
        v = np.asarray(list(itertools.islice(self.v, len(self.v) - k, None)), dtype=float)
        return t, v.reshape(k, self.width)

    def interp(self, tq: np.ndarray, angle_cols: tuple[int, ...] = ()) -> np.ndarray:
        """Values at times ``tq`` (linear, held at the ends); ``angle_cols`` (radians) are unwrapped
        first."""
        # only the recent part that brackets tq is converted (the ring holds minutes of samples)
        t0 = float(np.min(tq)) if len(tq) else np.inf
        k = 0
        for tk in reversed(self.t):
            k += 1
            if tk < t0:
                break
        t, v = self._tail(min(k + 1, len(self.t)))
        out = np.empty((len(tq), self.width))
        for j in range(self.width):
            col = np.unwrap(v[:, j]) if j in angle_cols else v[:, j]
            out[:, j] = np.interp(tq, t, col)
            if j in angle_cols:
                out[:, j] = np.arctan2(np.sin(out[:, j]), np.cos(out[:, j]))
        return out


class VehicleClock:
    """The vehicle's time now, estimated from the last telemetry time stamp and the observed clock
    rate.

    A real autopilot runs at rate 1; a SITL at its speed-up.  The rate is measured over the last few
    seconds of telemetry (falls back to ``rate_hint``), so that samples from a receiver that knows
    only the wall clock land at the right vehicle time.
    """

    def __init__(self, rate_hint: float = 1.0) -> None:
        self.rate = float(rate_hint)
        self._hist: deque[tuple[float, float]] = deque(maxlen=400)
        self.last_wall = -np.inf
        self.first: tuple[float, float] | None = None  # (wall, vehicle) of the first telemetry

    def update(self, t_vehicle: float) -> None:
        now = time.monotonic()
        if self.first is None or t_vehicle < self.first[1]:  # a rebooted vehicle restarts the count
            self.first = (now, t_vehicle)
        self._hist.append((now, t_vehicle))
        self.last_wall = now
        w0, v0 = self._hist[0]
        if now - w0 > 1.0 and t_vehicle > v0:
            self.rate = float(np.clip((t_vehicle - v0) / (now - w0), 0.05, 1000.0))
        while len(self._hist) > 2 and now - self._hist[0][0] > 5.0:
            self._hist.popleft()

    def now(self) -> float:
        """Estimated vehicle time (s); NaN before any telemetry."""
        if not self._hist:
            return float("nan")
        w, v = self._hist[-1]
        return v + (time.monotonic() - w) * self.rate

    def last_measured(self) -> float:
        """The vehicle time of the last telemetry (s), measured, never extrapolated; NaN before
        any."""
        return self._hist[-1][1] if self._hist else float("nan")

    def silent_for(self) -> float:
        """Wall-clock seconds since the last telemetry (inf before any)."""
        return time.monotonic() - self.last_wall

    def measured_speedup(self) -> float | None:
        """Vehicle seconds per wall-clock second over all telemetry so far (None before 1 s of
        it)."""
        if self.first is None or not self._hist:
            return None
        (w0, v0), (w1, v1) = self.first, self._hist[-1]
        return (v1 - v0) / (w1 - w0) if w1 - w0 >= 1.0 else None


class Telemetry:
    """Position (lat, lon, alt AMSL, rel. alt) and attitude (roll, pitch, yaw rad) series, and the
    clock."""

    def __init__(self, rate_hint: float = 1.0) -> None:
        self.pos = Series(4)
        self.att = Series(3)
        self.clock = VehicleClock(rate_hint)
        self.n_pos = self.n_att = 0
        self.t0_pos = self.t0_att = np.nan

    def add_position(self, t: float, lat: float, lon: float, alt: float, rel: float) -> None:
        if self.pos.add(t, (lat, lon, alt, rel)):
            if not self.n_pos:
                self.t0_pos = t
            self.n_pos += 1
            self.clock.update(t)

    def add_attitude(self, t: float, roll: float, pitch: float, yaw: float) -> None:
        if self.att.add(t, (roll, pitch, yaw)):
            if not self.n_att:
                self.t0_att = t
            self.n_att += 1
            self.clock.update(t)

    def summary(self) -> dict:
        """Measured speed-up (vehicle time per wall time) and telemetry rates (Hz of vehicle
        time)."""

        def rate(n: int, t0: float, t1: float) -> float | None:
            return round((n - 1) / (t1 - t0), 2) if n > 1 and t1 > t0 else None

        su = self.clock.measured_speedup()
        return {
            "speedup_measured": None if su is None else round(su, 3),
            "telemetry_rate_hz": {
                "position": rate(self.n_pos, self.t0_pos, self.pos.last_t),
                "attitude": rate(self.n_att, self.t0_att, self.att.last_t),
            },
        }

    @property
    def covered_until(self) -> float:
        """Latest time at which both position and attitude can be interpolated (not
        extrapolated)."""
        return min(self.pos.last_t, self.att.last_t)

    def at(self, tq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position (N, 4) and attitude (N, 3, radians, yaw wrapped to [0, 2 pi)) at times
        ``tq``."""
        p = self.pos.interp(tq)
        a = self.att.interp(tq, angle_cols=(0, 1, 2))
        a[:, 2] = np.mod(a[:, 2], 2 * np.pi)
        return p, a
