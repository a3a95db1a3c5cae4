"""The flight-log format: column names, the sidecar's layout and ``FlightLog``, a log in memory.

Reading (with its validation) is ``flightlog.read``, writing ``flightlog.write``;
``mission.flightlog`` exports all three.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mission import __version__
from mission.geo import Origin
from mission.samples import FlightSamples

WARNING = (
    "warning: "  # prefix of a FlightLog note that puts the result in doubt (not just a tidied row)
)
COLUMNS = (
    "t_s",
    "lat_deg",
    "lon_deg",
    "alt_m",
    "rel_alt_m",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "rss_dbm",
)
# The RSS a log may hold, dB(m): a real receiver's "dBm" is uncalibrated (the AFAR sounder reads up
# to +33), so "above 0 dBm" is no bound; a value outside this range is a unit or logging error, not
# a reading (+300 passed). The top leaves room for the fitted family's receiver offsets (normal,
# mean 69 dB, sd 16: its benchmark flight 4 of seed 2026 reads +101.6 near the transmitter, and a
# bound of 100 refused the project's own benchmark).
RSS_RANGE_DB = (-250.0, 150.0)
# The receiver's own quality per row, dB, where it reports one (the AFAR sounder's correlation peak
# over noise, ``mquality``; written by ``rfsl import afar-mat``).  Under SOUNDER_LOCK_DB the sounder
# has lost lock: on the six AFAR flights ``mquality`` follows the power from about -20 to 0 dB and
# sits on a 40-47 dB plateau below it whatever the power, and those rows read 23-37 dB under the
# model at the transmitter (``experiments/receiver_lock.py``).
QUALITY_COLUMN = "rss_quality_db"
SOUNDER_LOCK_DB = 50.0
# Columns that hold numbers or nothing: a text in one is a broken row (other extra columns, such as
# ``phase``, may hold text)
NUMERIC_COLUMNS = COLUMNS + (QUALITY_COLUMN,)
REQUIRED = ("t_s", "lat_deg", "lon_deg", "alt_m", "rel_alt_m", "rss_dbm")
OPTIONAL = ("roll_deg", "pitch_deg", "yaw_deg")
# Mission phase per row (extra columns written by flown and simulated logs): ``phase`` is one of
# PHASES, ``mission_item`` the 0-based index of the mission waypoint being flown to (-1 outside the
# mission phase); ``adaptive``: legs planned in flight from the live posterior
# (``mission.flight.adaptive``), item = their index. Two producers derive it:
# ``flight.phases.PhaseTracker`` from a flown vehicle's events, ``simulate.path_phases`` from a
# planned path's geometry; both name phases by these constants, in this order.
PHASES = ("ground", "takeoff", "mission", "adaptive", "return", "land")
GROUND, TAKEOFF, MISSION, ADAPTIVE, RETURN, LAND = PHASES
FLOWN_PHASES = (MISSION, ADAPTIVE)  # the legs a localizer uses
PHASE_COLUMNS = ("phase", "mission_item")


def sidecar_path(csv_path: str | Path) -> Path:
    """The JSON sidecar that belongs to a flight-log CSV."""
    return Path(csv_path).with_suffix(".json")


@dataclass
class FlightLog:
    """A flight log in memory: column arrays (float64, NaN where empty) and the sidecar metadata."""

    columns: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)
    path: Path | None = None
    # What reading accepted with a remark (CLIs print one line each); those that put the result in
    # doubt start with WARNING (no sidecar, a flight that did not complete).
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.columns["t_s"])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    @property
    def origin(self) -> Origin:
        """The mission origin from the sidecar (the first sample's ground if none is recorded)."""
        if "origin" in self.meta:
            return Origin.from_dict(self.meta["origin"])
        ground = float(self["alt_m"][0] - self["rel_alt_m"][0])
        return Origin(float(self["lat_deg"][0]), float(self["lon_deg"][0]), ground)

    @property
    def label(self) -> str:
        """The flight's name for titles: its folder for ``flights/<time>/flight.csv``, else the
        file's stem."""
        if self.path is None:
            return "flight"
        p = Path(self.path)
        return p.parent.name if p.stem == "flight" and p.parent.name else p.stem

    def enu(self, origin: Origin | None = None) -> np.ndarray:
        """UAV positions (N, 3) in the local ENU frame; z is the height above the origin's
        ground."""
        o = origin or self.origin
        return o.to_enu(self["lat_deg"], self["lon_deg"], self["alt_m"])

    @property
    def attitude_rad(self) -> np.ndarray | None:
        """(N, 3) roll, pitch, yaw in radians, or None when the log has no attitude."""
        att = np.stack([self[c] for c in OPTIONAL], axis=-1)
        if np.all(np.isnan(att)):
            return None
        return np.deg2rad(att)

    @property
    def truth_enu(self) -> np.ndarray | None:
        """True transmitter position (3,) in ENU metres when the sidecar knows it."""
        tx = self.meta.get("truth")
        if not tx:
            return None
        # exact local coordinates take precedence over lat/lon (no curvature round trip)
        if "x_m" in tx:
            return np.array([tx["x_m"], tx["y_m"], tx.get("z_m", 0.0)], dtype=float)
        o = self.origin
        enu = o.to_enu(tx["lat_deg"], tx["lon_deg"], o.alt_m + float(tx.get("height_m", 0.0)))
        # height above ground, not above the origin's tangent plane
        enu[2] = float(tx.get("height_m", 0.0))
        return enu

    def select(self, mask: np.ndarray) -> FlightLog:
        """A new log holding only the rows where ``mask`` is true."""
        return FlightLog(
            {k: v[mask] for k, v in self.columns.items()},
            dict(self.meta),
            self.path,
            list(self.notes),
        )

    def samples(self, origin: Origin | None = None) -> FlightSamples:
        """The log as ``FlightSamples`` (positions in ``origin``'s ENU frame, the log's own by
        default).

        The truth is the sidecar's, which is in the log's own frame: it is left out under another
        origin.
        """
        phase = self.columns.get("phase")
        own = origin is None or origin == self.origin
        return FlightSamples(
            enu_m=self.enu(origin),
            rss_dbm=np.asarray(self["rss_dbm"], dtype=float),
            attitude_rad=self.attitude_rad,
            t_s=np.asarray(self["t_s"], dtype=float),
            phase=phase if phase is not None and phase.dtype.kind in "OUS" else None,
            tx_enu_m=self.truth_enu if own else None,
            name=self.label,
            meta=dict(self.meta),
        )


def make_meta(origin: Origin, rss_source: dict, truth: dict | None = None, **extra) -> dict:
    """Sidecar metadata in the project's layout (``rss_source`` e.g. {"kind": "sim", "model": "e2r",
    "seed": 1})."""
    meta = {
        "format": "rfsl-flight-log/1",
        "software_version": __version__,
        "origin": origin.to_dict(),
        "rss_source": rss_source,
    }
    if truth is not None:
        meta["truth"] = truth
    meta.update(extra)
    return meta


def out_of_lock(quality: np.ndarray, lock_db: float = SOUNDER_LOCK_DB) -> np.ndarray:
    """Which rows the receiver read out of lock: quality under ``lock_db``, or unknown (NaN)."""
    return ~(np.asarray(quality, dtype=float) >= lock_db)


def lock_edges(
    quality: np.ndarray, lock_db: float = SOUNDER_LOCK_DB
) -> tuple[np.ndarray, np.ndarray]:
    """(the row before each loss of lock, the row after each regain), in row order: the locked
    reading next to each change of lock state (``out_of_lock``)."""
    locked = ~out_of_lock(quality, lock_db)
    change = np.flatnonzero(locked[1:] != locked[:-1])
    return change[locked[change]], change[~locked[change]] + 1


def lock_floor_db(
    power_db: np.ndarray, quality: np.ndarray, lock_db: float = SOUNDER_LOCK_DB
) -> float | None:
    """The level (in the log's power units) at which the receiver loses and regains lock: the
    median power of the locked reading next to each change of lock state (``lock_edges``).  On the
    AFAR flights lock is lost and regained at the same level (no hysteresis; out-of-lock runs of 1-3
    rows), -15 to -27 dB of ``mpower`` depending on the flight (``experiments/lock_mechanism.py``):
    what the receiver could hear, for a field team.  None without a change of state."""
    at = np.asarray(power_db, dtype=float)[np.concatenate(lock_edges(quality, lock_db))]
    at = at[np.isfinite(at)]
    return float(np.median(at)) if len(at) else None
