"""The flight-log format: one CSV per flight plus a JSON sidecar, written and read only here.

CSV columns (SPEC / issue 2): ``t_s, lat_deg, lon_deg, alt_m, rel_alt_m, roll_deg, pitch_deg, yaw_deg,
rss_dbm``.  Attitude may be empty (a receiver-only log).  Extra columns are kept, missing required ones
are refused.  The sidecar ``<name>.json`` beside the CSV holds the mission origin, the RSS source
(simulated: model and seed; or a real receiver, whose dB are not calibrated dBm), the software version and,
for simulated flights, the true transmitter position.
"""

from __future__ import annotations

import csv
import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mission import __version__
from mission.errors import InputError
from mission.geo import Origin, latlon_unit_problem

WARNING = "warning: "  # prefix of a FlightLog note that puts the result in doubt (not just a tidied row)
COLUMNS = ("t_s", "lat_deg", "lon_deg", "alt_m", "rel_alt_m", "roll_deg", "pitch_deg", "yaw_deg", "rss_dbm")
REQUIRED = ("t_s", "lat_deg", "lon_deg", "alt_m", "rel_alt_m", "rss_dbm")
OPTIONAL = ("roll_deg", "pitch_deg", "yaw_deg")
# Mission phase per row (extra columns written by flown and simulated logs): ``phase`` is one of PHASES,
# ``mission_item`` the 0-based index of the mission waypoint being flown to (-1 outside the mission phase).
PHASES = ("ground", "takeoff", "mission", "return", "land")
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
    # What reading accepted with a remark (CLIs print one line each); those that put the result in doubt
    # start with WARNING (no sidecar, a flight that did not complete).
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
        """The flight's name for titles: its folder for ``flights/<time>/flight.csv``, else the file's stem."""
        if self.path is None:
            return "flight"
        p = Path(self.path)
        return p.parent.name if p.stem == "flight" and p.parent.name else p.stem

    def enu(self, origin: Origin | None = None) -> np.ndarray:
        """UAV positions (N, 3) in the local ENU frame; z is the height above the origin's ground."""
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
        if "x_m" in tx:  # exact local coordinates take precedence over lat/lon (no curvature round trip)
            return np.array([tx["x_m"], tx["y_m"], tx.get("z_m", 0.0)], dtype=float)
        o = self.origin
        enu = o.to_enu(tx["lat_deg"], tx["lon_deg"], o.alt_m + float(tx.get("height_m", 0.0)))
        enu[2] = float(tx.get("height_m", 0.0))  # height above ground, not above the origin's tangent plane
        return enu

    def select(self, mask: np.ndarray) -> FlightLog:
        """A new log holding only the rows where ``mask`` is true."""
        return FlightLog({k: v[mask] for k, v in self.columns.items()}, dict(self.meta), self.path, list(self.notes))


def make_meta(origin: Origin, rss_source: dict, truth: dict | None = None, **extra) -> dict:
    """Sidecar metadata in the project's layout (``rss_source`` e.g. {"kind": "sim", "model": "e2r", "seed": 1})."""
    meta = {"format": "rfsl-flight-log/1", "software_version": __version__, "origin": origin.to_dict(),
            "rss_source": rss_source}
    if truth is not None:
        meta["truth"] = truth
    meta.update(extra)
    return meta


def _fmt(a: np.ndarray, digits: int) -> np.ndarray:
    s = np.char.mod(f"%.{digits}f", a)
    return np.where(np.isnan(a), "", s)


DIGITS = {"t_s": 4, "lat_deg": 9, "lon_deg": 9, "alt_m": 3, "rel_alt_m": 3, "roll_deg": 3,
          "pitch_deg": 3, "yaw_deg": 3, "rss_dbm": 4, "mission_item": 0}
DEFAULT_DIGITS = 6


def rounded(values, column: str) -> np.ndarray:
    """``values`` rounded exactly as the log writes ``column`` (decimal text read back): logged == used."""
    return np.char.mod(f"%.{DIGITS.get(column, DEFAULT_DIGITS)}f", np.asarray(values, dtype=float)).astype(float)


def format_rows(columns: dict[str, np.ndarray], header: tuple[str, ...]) -> str:
    """CSV text (no header) for column arrays, vectorised; NaN becomes an empty field.

    Numeric columns get the digits of ``DIGITS``; text columns (str/object arrays such as ``phase``) are
    written as they are and must not contain commas, quotes or newlines.
    """
    n = len(columns["t_s"])
    if n == 0:
        return ""
    cols = []
    for c in header:
        v = columns.get(c)
        if v is not None and np.asarray(v).dtype.kind in "OUS":
            text = np.asarray(v).astype(str)
            if any(ch in "".join(np.unique(text)) for ch in ',"\n\r'):
                raise ValueError(f"text column {c!r} holds a comma, quote or newline")
            cols.append(text)
            continue
        v = np.full(n, np.nan) if v is None else np.asarray(v, dtype=float)
        cols.append(_fmt(v, DIGITS.get(c, DEFAULT_DIGITS)))
    lines = cols[0]
    for c in cols[1:]:
        lines = np.char.add(np.char.add(lines, ","), c)
    return "\n".join(lines.tolist()) + "\n"


class FlightLogWriter:
    """Appends rows to a flight log and flushes them to disk, so a crash loses at most the unflushed rows.

    The sidecar is written when the writer opens (so a log is never without its metadata) and rewritten
    by ``close`` (with ``meta_updates`` such as the end status).
    """

    def __init__(self, path: str | Path, meta: dict, extra_columns: tuple[str, ...] = ()) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise InputError("refusing to overwrite an existing flight log", source=str(self.path))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.header = COLUMNS + tuple(extra_columns)
        self.meta = dict(meta)
        self.rows = 0
        self._f = open(self.path, "w", newline="")
        self._f.write(",".join(self.header) + "\n")
        self._write_sidecar()
        self.flush()

    def _write_sidecar(self) -> None:
        tmp = sidecar_path(self.path).with_suffix(".json.tmp")
        tmp.write_text(json.dumps(self.meta, indent=2, default=float))
        os.replace(tmp, sidecar_path(self.path))

    def append(self, columns: dict[str, np.ndarray]) -> None:
        """Append rows given as column arrays (missing optional columns are written empty)."""
        text = format_rows(columns, self.header)
        self._f.write(text)
        self.rows += len(columns["t_s"])

    def flush(self) -> None:
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self, **meta_updates) -> None:
        if self._f.closed:
            return
        self.flush()
        self._f.close()
        self.meta.update(meta_updates)
        self.meta["rows"] = self.rows
        self._write_sidecar()

    def __enter__(self) -> FlightLogWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_flight_log(path: str | Path, columns: dict[str, np.ndarray], meta: dict) -> Path:
    """Write a whole log (CSV + sidecar) at once, e.g. from the simulator; columns beyond ``COLUMNS``
    (such as ``PHASE_COLUMNS``) are written after them in the dict's order."""
    with FlightLogWriter(path, meta, extra_columns=tuple(c for c in columns if c not in COLUMNS)) as w:
        w.append(columns)
    return Path(path)


def _parse_column(values: list[str], name: str, source: str, allow_empty: bool) -> np.ndarray:
    arr = np.array([v.strip() for v in values], dtype=object)
    empty = arr == ""
    if not allow_empty and empty.any():
        row = int(np.argmax(empty)) + 2
        raise InputError("empty value in a required column", source=source, row=row, field=name)
    arr[empty] = "nan"
    try:
        out = arr.astype(float)
    except ValueError:
        for i, v in enumerate(arr):  # error path only: find the offending row
            try:
                float(v)
            except ValueError:
                raise InputError(f"not a number: {v!r}", source=source, row=i + 2, field=name) from None
        raise
    if not allow_empty and np.isnan(out).any():
        row = int(np.argmax(np.isnan(out))) + 2
        raise InputError("NaN in a required column", source=source, row=row, field=name)
    if np.isinf(out).any():
        row = int(np.argmax(np.isinf(out))) + 2
        raise InputError("infinite value", source=source, row=row, field=name)
    return out


def read_flight_log(path: str | Path, origin: Origin | None = None) -> FlightLog:
    """Read and validate a flight log; any problem is an ``InputError`` naming the file, row and column.

    Rows are numbered as lines of the file (the header is line 1).  Real-log quirks are accepted with a
    note in ``FlightLog.notes``: repeated timestamps (first kept), a last line cut short by a crash
    (dropped), a missing sidecar, a flight the sidecar says did not complete.  ``origin`` (e.g. from
    ``--origin``) replaces the sidecar's.
    """
    path = Path(path)
    src = str(path)
    if path.is_dir():
        some = ", ".join(p.name for p in sorted(path.glob("*.csv"))[:3])
        raise InputError(f"is a directory, not a flight-log CSV{f' (it holds {some})' if some else ''}", source=src)
    if not path.exists():
        raise InputError("no such flight log", source=src)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a spreadsheet's byte-order mark is not part of "t_s"
    except UnicodeDecodeError:
        raise InputError("not a text CSV file", source=src) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", source=src) from None
    notes: list[str] = []
    reader = csv.reader(io.StringIO(text))
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise InputError("empty file (no header)", source=src) from None
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(f"missing required column(s) {', '.join(missing)}; header is {','.join(header)}",
                         source=src)
    text, cut = _drop_cut_last_line(text, header, _written_here(path))
    if cut:
        notes.append(cut)
        reader = csv.reader(io.StringIO(text))
        next(reader)
    fast = _fast_numeric(text, header)
    if fast is not None:
        columns = dict(zip(header, fast.T, strict=True))
        n = fast.shape[0]
        for name in REQUIRED:  # NaN (or empty) in a required column: the slow path names the row
            if np.isnan(columns[name]).any():
                fast = None
                break
    if fast is None:
        columns, n = _slow_parse(reader, header, src)
    for c in OPTIONAL:
        columns.setdefault(c, np.full(n, np.nan))
    return _validated(columns, path, src, notes, origin)


def _written_here(path: Path) -> bool:
    """True when the log's sidecar says ``FlightLogWriter`` wrote it (so every complete row ends in a newline)."""
    try:
        meta = json.loads(sidecar_path(path).read_text())
        return isinstance(meta, dict) and str(meta.get("format", "")).startswith("rfsl-flight-log")
    except (OSError, ValueError):
        return False


def _drop_cut_last_line(text: str, header: list[str], newline_ends_rows: bool = False) -> tuple[str, str | None]:
    """Drop a last line cut short (fields missing, a required value empty or unreadable, or, in a log this
    project wrote, no line end) and say so.

    Why: a logger killed mid-write leaves exactly this, and the rows before it are good; the same damage
    in the middle of a file is refused by the parser with its row.  ``FlightLogWriter`` ends every row with a
    newline, so in its logs a last line without one was cut even when what is left still parses (-71.5 -> -7).
    """
    lines = text.rstrip().splitlines()
    if len(lines) < 3:  # header + one data row: nothing would be left, let the parser report it
        return text, None
    fields = next(csv.reader([lines[-1]]), [])
    reason = None
    if newline_ends_rows and not text.endswith("\n"):
        reason = "no line end"
    elif len(fields) != len(header):
        reason = f"{len(fields)} of {len(header)} fields"
    else:
        for name, v in zip(header, fields, strict=True):
            if name not in COLUMNS or (not v.strip() and name not in REQUIRED):
                continue
            try:
                ok = np.isfinite(float(v))
            except ValueError:
                ok = False
            if not ok:
                reason = f"field '{name}' is {v.strip()!r}"
                break
    if reason is None:
        return text, None
    return ("\n".join(lines[:-1]) + "\n",
            f"dropped the last line (row {len(lines)}), cut short ({reason}) as when a logger stops mid-write")


def _fast_numeric(text: str, header: list[str]) -> np.ndarray | None:
    """All-numeric CSV body -> (rows, cols) float array in one vectorised conversion, or None.

    Empty fields become NaN.  Anything unusual (text columns, ragged rows, bad numbers) returns None and
    the caller falls back to the row-by-row parser, which names the offending row.
    """
    body = text.split("\n", 1)[1] if "\n" in text else ""
    lines = [ln for ln in body.splitlines() if ln.strip()]
    if not lines:
        return None
    width = len(header)
    joined = ",".join(lines)
    tokens = joined.split(",")
    if len(tokens) != width * len(lines):
        return None
    arr = np.array(tokens, dtype=object)
    arr[arr == ""] = "nan"
    try:
        out = arr.astype(float).reshape(len(lines), width)
    except ValueError:
        return None
    if np.isinf(out).any():
        return None
    return out


def _slow_parse(reader, header: list[str], src: str) -> tuple[dict[str, np.ndarray], int]:
    """Row-by-row parse with exact error locations (fallback for unusual or broken files)."""
    rows = [r for r in reader if r]
    if not rows:
        raise InputError("no data rows", source=src)
    width = len(header)
    for i, r in enumerate(rows):
        if len(r) != width:
            raise InputError(f"expected {width} fields, found {len(r)}", source=src, row=i + 2)
    cols_text = list(zip(*rows, strict=True))
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        allow_empty = name not in REQUIRED
        try:
            columns[name] = _parse_column(list(cols_text[j]), name, src, allow_empty)
        except InputError:
            if name in COLUMNS:
                raise
            columns[name] = np.array(cols_text[j], dtype=object)  # extra non-numeric column: keep as text
    return columns, len(rows)


# Magnitudes no real value reaches: a larger one is a unit or logging error, not data (1e300 dBm gave NaN).
_ABS_LIMITS = {"rss_dbm": 400.0, "alt_m": 20000.0, "rel_alt_m": 20000.0}


def _validated(columns: dict[str, np.ndarray], path: Path, src: str, notes: list[str] | None = None,
               origin: Origin | None = None) -> FlightLog:
    """Check time order, units and ranges; attach the sidecar; drop repeated timestamps with a note."""
    notes = [] if notes is None else notes
    t = columns["t_s"]
    bad = np.flatnonzero(np.diff(t) < 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"time goes backwards ({t[i - 1]} then {t[i]})", source=src, row=i + 2, field="t_s")
    lat, lon = columns["lat_deg"], columns["lon_deg"]
    for name, arr, lim in (("lat_deg", lat, 90.0), ("lon_deg", lon, 180.0)):
        badv = np.flatnonzero(np.abs(arr) > lim)
        if badv.size:
            raise InputError(f"{arr[badv[0]]} is outside +-{lim} degrees (wrong units?)", source=src,
                             row=int(badv[0]) + 2, field=name)
    for name in ("roll_deg", "pitch_deg"):
        badv = np.flatnonzero(np.abs(np.nan_to_num(columns[name])) > 180.0)
        if badv.size:
            raise InputError(f"{columns[name][badv[0]]} is outside +-180 degrees (radians given?)", source=src,
                             row=int(badv[0]) + 2, field=name)
    for name, lim in _ABS_LIMITS.items():
        badv = np.flatnonzero(np.abs(columns[name]) > lim)
        if badv.size:
            raise InputError(f"{columns[name][badv[0]]:g} is not a plausible value (|value| > {lim:g})", source=src,
                             row=int(badv[0]) + 2, field=name)
    meta = _read_sidecar(path, notes, origin_given=origin is not None)
    if origin is not None:
        if "origin" in meta:
            notes.append("the origin given replaces the sidecar's")
        meta["origin"] = origin.to_dict()
    problem = latlon_unit_problem(lat, lon, Origin.from_dict(meta["origin"]) if "origin" in meta else None)
    if problem:
        raise InputError(problem[1], source=src, row=problem[0] + 2, field="lat_deg")
    dup = np.diff(t) == 0
    if dup.any():
        keep = np.concatenate([[True], ~dup])
        columns = {k: v[keep] for k, v in columns.items()}
        notes.append(f"dropped {int(dup.sum())} row(s) whose time repeats the previous row's (first kept), "
                     f"e.g. row {int(np.argmax(dup)) + 3}")
    n = len(columns["t_s"])
    if n < 2:
        raise InputError(f"only {n} data row; a flight log needs at least 2", source=src)
    return FlightLog(columns, meta, path, notes)


def _read_sidecar(path: Path, notes: list[str], origin_given: bool = False) -> dict:
    """The sidecar's metadata, its origin and truth checked (an InputError names the sidecar and key)."""
    sc = sidecar_path(path)
    if not sc.exists():
        where = ("the origin given" if origin_given else
                 "its origin at the first sample (give --origin LAT,LON[,ALT] for the mission's frame)")
        notes.append(f"{WARNING}no sidecar {sc.name}: read as an uncalibrated receiver log with {where} and no truth")
        return {}
    try:
        meta = json.loads(sc.read_text())
    except json.JSONDecodeError as e:
        raise InputError(f"sidecar is not valid JSON ({e.msg} at line {e.lineno})", source=str(sc)) from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read the sidecar ({e})", source=str(sc)) from None
    if not isinstance(meta, dict):
        raise InputError(f"sidecar must be a JSON object, got {type(meta).__name__}", source=str(sc))

    def num(d: dict, key: str, where: str, lim: float | None = None, required: bool = True) -> None:
        v = d.get(key)
        if v is None and not required:
            return
        ok = isinstance(v, int | float) and not isinstance(v, bool) and np.isfinite(v)
        if not ok or (lim is not None and abs(v) > lim):
            what = f"a number within +-{lim:g}" if lim is not None else "a finite number"
            raise InputError(f"expected {what}, got {v!r}", source=str(sc), field=f"{where}.{key}")

    o = meta.get("origin")
    if o is not None:
        if not isinstance(o, dict):
            raise InputError("expected {lat_deg, lon_deg, alt_m}", source=str(sc), field="origin")
        num(o, "lat_deg", "origin", 90.0)
        num(o, "lon_deg", "origin", 180.0)
        num(o, "alt_m", "origin", _ABS_LIMITS["alt_m"], required=False)
    tr = meta.get("truth")
    if tr:
        if not isinstance(tr, dict):
            raise InputError("expected {lat_deg, lon_deg, height_m} or {x_m, y_m, z_m}", source=str(sc),
                             field="truth")
        if "x_m" in tr:
            for k in ("x_m", "y_m", "z_m"):
                num(tr, k, "truth", 1e6, required=k != "z_m")
        else:
            num(tr, "lat_deg", "truth", 90.0)
            num(tr, "lon_deg", "truth", 180.0)
        for k in ("z_m", "height_m"):
            num(tr, k, "truth", 1e4, required=False)
            if tr.get(k) is not None and tr[k] < 0:
                raise InputError(f"transmitter below ground ({tr[k]:g} m)", source=str(sc), field=f"truth.{k}")
    status = meta.get("status")
    if status is not None and status != "completed":
        notes.append(f"{WARNING}the sidecar says the flight did not complete (status {status!r}): the log may end "
                     "early or miss part of the pattern")
    return meta
