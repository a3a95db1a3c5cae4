"""AFAR challenge MAT files (AERPAW, December 2023) -> project flight logs (CSV + JSON sidecar).

Variables read (``../shared/data/README.md``): ``timestamp_power`` (s, node wall clock), ``mX``
longitude, ``mY`` latitude, ``mZ`` height above the *first GPS fix* (m),
``mRoll``/``mPitch``/``mYaw`` (deg, yaw clockwise from north) and ``mpower`` (channel-sounder dB,
NOT calibrated dBm); ``mquality`` (correlation peak over noise, dB), when the file has it, becomes
the extra column ``rss_quality_db``.

Choices:

- Origin: the AFAR field origin (``mission.geo.afar_field().origin``, the flight-area SW corner, 0
  m), so every imported log shares one local frame.
- ``alt_m = rel_alt_m = mZ``: the files carry no AMSL altitude; ``mZ`` is height above the first fix
  (about 3-4 m below the autopilot's relative altitude), which is used as the height above the
  origin's ground.
- ``t_s`` is seconds since the first kept sample; the absolute start time goes into the sidecar.
- Out-of-order rows are sorted; duplicate timestamps, and samples less than 1 ms after the previous
  one (the sounder's values are time-stamped when read from a pipe, and about 15 per flight come in
  bursts some 20 us apart, below the log's 0.1 ms resolution), are dropped (first kept); the
  sidecar's ``import_notes`` says how many.
- Truth is only ever taken from the caller (``--truth``), never guessed from the file name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.io as sio

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.flightlog import FlightLog, make_meta, write_flight_log
from mission.flightlog.schema import QUALITY_COLUMN, RSS_RANGE_DB
from mission.geo import Origin, afar_field, latlon_unit_problem

REQUIRED_VARS = ("timestamp_power", "mX", "mY", "mZ", "mRoll", "mPitch", "mYaw", "mpower")
# Read when present: the sounder's correlation peak over noise, dB (``../shared/data/README.md``),
# written as the column ``QUALITY_COLUMN`` (what it says: ``mission.flightlog.schema``)
OPTIONAL_VARS = ("mquality",)
MIN_DT_S = (
    1e-3  # samples closer than this to the previous one count as duplicates (log resolution 0.1 ms)
)
# Rover (transmitter) truth of the AFAR 2023 challenge flights by location number in the MAT file
# name (``../shared/data/README.md``); antenna about 1.5 m above ground.
AFAR2023_TRUTH: dict[int, tuple[float, float]] = {
    1: (35.72806709, -78.69730398),
    2: (35.72911779, -78.69918128),
    3: (35.72985129, -78.69711002),
}
# The one flight whose truth label is suspect, as (team, location): its strongest airborne RSS
# sample lies 147 m from the labelled point (team 328 at the same location: 73 m). Benchmarks never
# fit on it and report it apart.
AFAR2023_SUSPECT: tuple[int, int] = (288, 3)
AFAR2023_SUSPECT_NOTE = (
    "team 288 location 3 is suspect: strongest RSS about 147 m from the labelled point"
)

# Leave-one-team-out: the ``afar`` preset fold fitted without each team (``afar:fit328`` saw only
# team 328's flights), the physics a held-out score of that team's flights may use
AFAR2023_FOLD_WITHOUT: dict[str, str] = {"288": "fit328", "328": "fit288"}


def afar2023_id(name: str | Path) -> tuple[int, int] | None:
    """(team, location) of an AFAR 2023 flight from any of its names: a MAT/log file
    ``results_useful_ori_exp_288_loc_3.mat``, a stem ``288_loc_3`` or a benchmark flight
    ``288-loc3``; None for other names."""
    m = re.search(r"(\d+)(?:_loc_|-loc)(\d+)", Path(name).name)
    return (int(m.group(1)), int(m.group(2))) if m else None


def is_afar2023_suspect(name: str | Path) -> bool:
    """Whether ``name`` (any form ``afar2023_id`` reads) is the flight with the suspect truth
    label."""
    return afar2023_id(name) == AFAR2023_SUSPECT


RSS_SOURCE = {"kind": "real", "receiver": "AERPAW channel sounder", "calibrated": False}


@dataclass
class ImportResult:
    """One imported flight: its log (in memory), what was done to it, and where it was written."""

    log: FlightLog
    notes: list[str] = field(default_factory=list)
    out_path: Path | None = None


def _load_mat(path: Path) -> dict[str, np.ndarray]:
    src = str(path)
    if path.is_dir():
        raise InputError(
            "is a directory, not a MAT file (give the folder to `rfsl import` to import every .mat "
            "in it)",
            source=src,
        )
    if not path.exists():
        raise InputError("no such MAT file", source=src)
    try:
        m = sio.loadmat(str(path))
    except Exception as e:  # scipy raises several types for non-MAT input
        raise InputError(
            f"not a readable MATLAB file ({type(e).__name__}: {e})".splitlines()[0], source=src
        ) from None
    missing = [v for v in REQUIRED_VARS if v not in m]
    if missing:
        raise InputError(f"missing MAT variable(s) {', '.join(missing)}", source=src)
    out: dict[str, np.ndarray] = {}
    n = None
    for v in REQUIRED_VARS + tuple(o for o in OPTIONAL_VARS if o in m):
        try:
            a = np.asarray(m[v], dtype=float).ravel()
        except (TypeError, ValueError):
            raise InputError("not numeric", source=src, field=v) from None
        if n is None:
            n = a.size
        elif a.size != n:
            raise InputError(
                f"has {a.size} rows, expected {n} (as timestamp_power)", source=src, field=v
            )
        out[v] = a
    if not n:
        raise InputError("no samples", source=src)
    return out


# What no sample of a real flight can hold, per MAT variable: (low, high, what it means). The power
# is the uncalibrated receiver's dB (RSS_RANGE_DB: the AFAR sounder reads up to +33, so 0 dBm is no
# bound); attitude within +-180 (yaw, wrapped later, within ten turns); the time stamps are Unix
# seconds.
IMPOSSIBLE = {
    "mpower": (*RSS_RANGE_DB, f"power outside {RSS_RANGE_DB[0]:g}..{RSS_RANGE_DB[1]:g} dB"),
    "mRoll": (-180.0, 180.0, "roll outside +-180 deg"),
    "mPitch": (-180.0, 180.0, "pitch outside +-180 deg"),
    "mYaw": (-3600.0, 3600.0, "yaw beyond ten turns"),
    "mZ": (-1000.0, 20000.0, "height outside -1..20 km"),
    "timestamp_power": (0.0, 1e11, "time stamp that is not Unix seconds"),
}
MAX_SPAN_S = 86400.0  # one flight's time stamps span less than a day


def _drop_impossible(m: dict[str, np.ndarray], notes: list[str]) -> dict[str, np.ndarray]:
    """Drop the samples holding a physically impossible value, with one note per kind naming the
    samples (1-based, as in the MAT file); and those whose time stamp lies a day or more from the
    flight's median."""
    bad_all = np.zeros(m["timestamp_power"].size, dtype=bool)
    for v, (lo, hi, what) in IMPOSSIBLE.items():
        bad = np.asarray(~((m[v] >= lo) & (m[v] <= hi)) & np.isfinite(m[v]))
        if v == "timestamp_power" and not bad.all():
            t = m[v]
            bad |= np.abs(t - np.median(t[~bad])) > MAX_SPAN_S
        if bad.any():
            rows = np.flatnonzero(bad) + 1
            shown = ", ".join(map(str, rows[:5])) + (", ..." if rows.size > 5 else "")
            notes.append(f"dropped {rows.size} sample(s) with {what} ({v}; sample {shown})")
        bad_all |= bad
    return {k: a[~bad_all] for k, a in m.items()} if bad_all.any() else m


QUALITY_RANGE_DB = (-100.0, 300.0)  # a correlation peak over noise outside this is no reading


def _quality(q: np.ndarray, notes: list[str]) -> np.ndarray:
    """``mquality`` as the log's quality column: a value no sounder gives (infinite, or outside
    ``QUALITY_RANGE_DB``) becomes unknown (NaN, read as out of lock), with a note; the sample's
    power and position are kept."""
    lo, hi = QUALITY_RANGE_DB
    bad = np.isinf(q) | (q < lo) | (q > hi)
    if not bad.any():
        return q
    notes.append(
        f"{int(bad.sum())} quality value(s) outside {lo:g}..{hi:g} dB (mquality) read as unknown"
    )
    return np.where(bad, np.nan, q)


def convert_afar_mat(
    path: str | Path,
    truth: tuple[float, float] | None = None,
    truth_height_m: float = DEFAULT_TX_HEIGHT_M,
    origin: Origin | None = None,
) -> ImportResult:
    """Read one AFAR MAT file and return the flight log (not yet written) plus import notes."""
    path = Path(path)
    src = str(path)
    m = _load_mat(path)
    notes: list[str] = []
    m = _usable_rows(m, notes, src)
    t = m["timestamp_power"]
    lat, lon = m["mY"], m["mX"]
    if np.any(np.abs(lat) > 90) or np.any(np.abs(lon) > 180):
        raise InputError("mY/mX are not latitude/longitude in degrees", source=src, field="mY")
    origin = origin or afar_field().origin
    problem = latlon_unit_problem(lat, lon, origin)
    if problem:
        raise InputError(f"sample {problem[0]}: mY/mX {problem[1]}", source=src, field="mY")
    if not truth_height_m >= 0:
        raise InputError(
            f"transmitter height {truth_height_m:g} m is below ground", field="--truth-height"
        )
    z = m["mZ"]
    cols = {
        "t_s": t - t[0],
        "lat_deg": lat,
        "lon_deg": lon,
        "alt_m": origin.alt_m + z,
        "rel_alt_m": z,
        "roll_deg": m["mRoll"],
        "pitch_deg": m["mPitch"],
        "yaw_deg": np.mod(m["mYaw"], 360.0),
        "rss_dbm": m["mpower"],
    }
    if "mquality" in m:
        cols[QUALITY_COLUMN] = _quality(m["mquality"], notes)
    meta = _sidecar_meta(path, origin, t[0], truth, truth_height_m, notes)
    return ImportResult(FlightLog(cols, meta), notes)


def _usable_rows(m: dict, notes: list[str], src: str) -> dict:
    """The rows kept: finite, physically possible, in time order, one per timestamp and at least
    ``MIN_DT_S`` apart; each drop is a note. Fewer than 2 left: ``InputError``."""
    finite = np.ones(m["timestamp_power"].size, dtype=bool)
    for v in ("timestamp_power", "mX", "mY", "mZ", "mpower"):
        finite &= np.isfinite(m[v])
    if not finite.all():
        notes.append(f"dropped {int((~finite).sum())} rows with NaN/inf time, position or power")
        m = {k: a[finite] for k, a in m.items()}
    m = _drop_impossible(m, notes)
    if m["timestamp_power"].size < 2:
        raise InputError(
            "fewer than 2 usable samples" + (f" ({notes[-1]})" if notes else ""), source=src
        )
    t = m["timestamp_power"]
    if np.any(np.diff(t) < 0):
        notes.append(f"sorted {int((np.diff(t) < 0).sum())} out-of-order timestamps")
    order = np.argsort(t, kind="stable")
    t = t[order]
    keep = np.concatenate([[True], np.diff(t) > 0])
    if not keep.all():
        notes.append(f"dropped {int((~keep).sum())} rows with duplicate timestamps")
    t = t[keep]
    order = order[keep]
    near = np.concatenate([[False], np.diff(t) < MIN_DT_S])
    if near.any():
        notes.append(
            f"dropped {int(near.sum())} rows less than {MIN_DT_S * 1e3:g} ms after the "
            "previous one "
            "(receiver read bursts; the log stores 0.1 ms)"
        )
    keep = ~near
    idx = order[keep]
    return {k: a[idx] for k, a in m.items()}


def _sidecar_meta(path: Path, origin: Origin, t0: float, truth, truth_height_m: float, notes):
    """The sidecar of an imported flight: origin, the receiver, the truth when given, the source
    file and its start time, and the import notes."""
    truth_d = None
    if truth is not None:
        truth_d = {
            "lat_deg": float(truth[0]),
            "lon_deg": float(truth[1]),
            "height_m": float(truth_height_m),
        }
    start = np.datetime64(int(round(t0 * 1e6)), "us")
    meta = make_meta(
        origin,
        dict(RSS_SOURCE),
        truth_d,
        source={
            "file": path.name,
            "format": "AFAR challenge MAT (MPACT-Lab results_useful_ori)",
            "start_time_utc": str(start),
        },
        altitude_reference="mZ: height above the first GPS fix (used as alt_m and rel_alt_m)",
        import_notes=notes,
    )
    return meta


def import_afar_mat(
    path: str | Path,
    out_dir: str | Path,
    truth: tuple[float, float] | None = None,
    truth_height_m: float = DEFAULT_TX_HEIGHT_M,
    overwrite: bool = False,
) -> ImportResult:
    """Convert one MAT file and write ``out_dir/<stem>.csv`` + sidecar; the result carries
    ``out_path``."""
    res = convert_afar_mat(path, truth, truth_height_m)
    if Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise InputError("is a file, not an output folder", source=str(out_dir), field="--out")
    out = Path(out_dir) / (Path(path).stem + ".csv")
    for p in (out, out.with_suffix(".json")):
        if p.exists() and not overwrite:
            raise InputError("output exists (use --overwrite)", source=str(p))
    write_flight_log(out, res.log.columns, res.log.meta, overwrite=overwrite)
    res.out_path = out
    res.log.path = out
    return res
