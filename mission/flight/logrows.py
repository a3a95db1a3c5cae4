"""Log rows of a flight: RSS samples joined with telemetry and phase, rounded as written, appended.

Why: every RSS sample (simulated or from a receiver) becomes one row with the position and attitude
interpolated to its vehicle time and the mission phase at that time.  Values are rounded exactly as
the log writes them (``flightlog.rounded``) *before* the sim source evaluates its model, so a log's
RSS is reproducible offline from its own rows.  The file is fsynced at least twice a second.
"""

from __future__ import annotations

import datetime as _dt
import time
from pathlib import Path

import numpy as np

from mission.flightlog import rounded

POSITION_COLUMNS = ("lat_deg", "lon_deg", "alt_m", "rel_alt_m")
ATTITUDE_COLUMNS = ("roll_deg", "pitch_deg", "yaw_deg")
FLUSH_EVERY_S = 0.5


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
    raise FileExistsError(f"cannot create a new flight folder under {out}")


class RowLogger:
    """Drains an RSS source up to the telemetry's coverage and appends the joined rows to a log
    writer."""

    def __init__(self, writer, source, tel, phases, origin, status) -> None:
        self.writer, self.source, self.tel, self.phases = writer, source, tel, phases
        self.origin, self.status = origin, status
        self.t_ref: float | None = None
        self._last_flush = 0.0
        self.on_error = (
            None  # called once with the OSError of a failed write (the flight decides what next)
        )

    def write(self, final: bool = False) -> None:
        """Append every sample the telemetry covers (``final``: receivers' samples up to now as
        well); a failed write (disk full) goes to ``on_error`` once, never up into the caller."""
        self._guard(self._write, final)

    def flush(self) -> None:
        """Rows written so far onto the disk (a failure as in ``write``)."""
        self._guard(self.writer.flush)

    def _guard(self, fn, *args) -> None:
        try:
            fn(*args)
        except OSError as e:
            if self.on_error is None:
                raise
            self.on_error(e)

    def _write(self, final: bool) -> None:
        if not self.tel.n_pos or not self.tel.n_att:
            return
        t_until = self.tel.covered_until
        if final and not self.source.needs_model:
            t_until = np.inf  # receivers: keep every sample; telemetry is held at the ends
        t, vals, extra = self.source.drain(t_until)
        if len(t):
            self._append(t, vals, extra)
        now = time.monotonic()
        if final or now - self._last_flush >= FLUSH_EVERY_S:
            self.writer.flush()
            self._last_flush = now

    def _append(self, t: np.ndarray, vals, extra: dict) -> None:
        if self.t_ref is None:
            self.t_ref = float(t[0])
            self.writer.meta["t0_vehicle_s"] = self.t_ref
        pos, att = self.tel.at(t)
        att_deg = np.rad2deg(att)
        cols = {"t_s": rounded(t - self.t_ref, "t_s")}
        cols.update({c: rounded(pos[:, j], c) for j, c in enumerate(POSITION_COLUMNS)})
        cols.update({c: rounded(att_deg[:, j], c) for j, c in enumerate(ATTITUDE_COLUMNS)})
        if vals is None:
            vals = self.source.evaluate(
                cols["lat_deg"],
                cols["lon_deg"],
                cols["alt_m"],
                np.stack([cols[c] for c in ATTITUDE_COLUMNS], -1),
            )
        cols["rss_dbm"] = np.asarray(vals, dtype=float)
        cols["phase"], cols["mission_item"] = self.phases.at(t)
        cols.update(extra)
        self.writer.append(cols)
        s = self.status
        s.rows = self.writer.rows
        s.last_rss = float(cols["rss_dbm"][-1])
        i = int(np.argmax(cols["rss_dbm"]))
        if cols["rss_dbm"][i] > s.best_rss:
            s.best_rss = float(cols["rss_dbm"][i])
            enu = self.origin.to_enu(cols["lat_deg"][i], cols["lon_deg"][i], cols["alt_m"][i])
            s.best_xy = (float(enu[0]), float(enu[1]))
