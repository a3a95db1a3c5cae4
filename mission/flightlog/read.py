"""Reading flight logs: parse and validate a CSV and its sidecar into a ``FlightLog``.

Any problem is an ``InputError`` naming the file, row and column; real-log quirks (repeated
timestamps, a last line cut by a crash, no sidecar, an incomplete flight) are accepted with a note.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.fields import Fields, check_types
from mission.files import check_regular, read_bytes, read_text
from mission.flightlog.schema import (
    NUMERIC_COLUMNS,
    OPTIONAL,
    REQUIRED,
    RSS_RANGE_DB,
    WARNING,
    FlightLog,
    sidecar_path,
)
from mission.geo import Origin, latlon_unit_problem


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
                raise InputError(
                    f"not a number: {v!r}", source=source, row=i + 2, field=name
                ) from None
        raise
    if not allow_empty and np.isnan(out).any():
        row = int(np.argmax(np.isnan(out))) + 2
        raise InputError("NaN in a required column", source=source, row=row, field=name)
    if np.isinf(out).any():
        row = int(np.argmax(np.isinf(out))) + 2
        raise InputError("infinite value", source=source, row=row, field=name)
    return out


def read_flight_log(path: str | Path, origin: Origin | None = None) -> FlightLog:
    """Read and validate a flight log; any problem is an ``InputError`` naming the file, row and
    column.

    Rows are numbered as lines of the file (the header is line 1).  Real-log quirks are accepted
    with a note in ``FlightLog.notes``: repeated timestamps (first kept), a last line cut short by a
    crash (dropped), a missing sidecar, a flight the sidecar says did not complete.  ``origin``
    (e.g. from ``--origin``) replaces the sidecar's.
    """
    path = Path(path)
    src = str(path)
    if path.is_dir():
        some = ", ".join(p.name for p in sorted(path.glob("*.csv"))[:3])
        raise InputError(
            f"is a directory, not a flight-log CSV{f' (it holds {some})' if some else ''}",
            source=src,
        )
    check_regular(path, "flight log")  # a FIFO or /dev/zero would block or never end
    try:
        # a spreadsheet's BOM is not part of "t_s"
        text = read_bytes(path, "flight log").decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError("not a text CSV file", source=src) from None
    notes: list[str] = []
    reader = csv.reader(io.StringIO(text))
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise InputError("empty file (no header)", source=src) from None
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(
            f"missing required column(s) {', '.join(missing)}; header is {','.join(header)}",
            source=src,
        )
    text, cut = _drop_cut_last_line(text, header, _written_here(path))
    if cut:
        notes.append(cut)
        reader = csv.reader(io.StringIO(text))
        next(reader)
    columns = _fast_parse(text, header)
    if columns is not None and any(np.isnan(columns[c]).any() for c in REQUIRED):
        columns = None  # NaN (or empty) in a required column: the slow path names the row
    if columns is None:
        columns, _ = _slow_parse(reader, header, src)
    n = len(columns["t_s"])
    for c in OPTIONAL:
        columns.setdefault(c, np.full(n, np.nan))
    return _validated(columns, path, src, notes, origin)


def _written_here(path: Path) -> bool:
    """True when the log's sidecar says ``FlightLogWriter`` wrote it (so every complete row ends in
    a newline)."""
    try:
        meta = json.loads(sidecar_path(path).read_text())
        return isinstance(meta, dict) and str(meta.get("format", "")).startswith("rfsl-flight-log")
    except (OSError, ValueError, RecursionError):
        return False


def _drop_cut_last_line(
    text: str, header: list[str], newline_ends_rows: bool = False
) -> tuple[str, str | None]:
    """Drop a last line cut short (fields missing, a required value empty or unreadable, or, in a
    log this project wrote, no line end) and say so.

    Why: a logger killed mid-write leaves exactly this, and the rows before it are good; the same
    damage in the middle of a file is refused by the parser with its row.  ``FlightLogWriter`` ends
    every row with a newline, so in its logs a last line without one was cut even when what is left
    still parses (-71.5 -> -7).
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
            if name not in NUMERIC_COLUMNS or (not v.strip() and name not in REQUIRED):
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
    return (
        "\n".join(lines[:-1]) + "\n",
        f"dropped the last line (row {len(lines)}), cut short ({reason}) as when a logger "
        "stops mid-write",
    )


def _fast_parse(text: str, header: list[str]) -> dict[str, np.ndarray] | None:
    """The CSV body as column arrays in one vectorised pass, or None when anything is unusual.

    Numeric columns become float64 (an empty field NaN); an extra column that is not all numbers
    (``phase``) is kept as text, as the row-by-row parser keeps it.  Quotes, ragged rows, a bad
    number in a format column or an infinite value return None: the caller falls back to the
    row-by-row parser, which names the offending row.
    """
    body = text.split("\n", 1)[1] if "\n" in text else ""
    lines = [ln for ln in body.splitlines() if ln.strip()]
    if not lines or '"' in body:
        return None
    width = len(header)
    if any(ln.count(",") != width - 1 for ln in lines):
        return None
    raw = np.array(",".join(lines).split(","), dtype=object).reshape(len(lines), width)
    num = raw.copy()
    num[num == ""] = "nan"
    try:
        table = num.astype(float)  # all numeric: one conversion
    except ValueError:
        table = None
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        values = table[:, j] if table is not None else _as_float(num[:, j])
        # blank fields padded with spaces still read as NaN
        if values is None and name not in NUMERIC_COLUMNS:
            values = _as_float(
                np.where(np.char.strip(raw[:, j].astype(str)) == "", "nan", raw[:, j])
            )
        if values is None:
            if name in NUMERIC_COLUMNS:
                return None
            columns[name] = raw[:, j]  # extra non-numeric column (``phase``): kept as text
        elif np.isinf(values).any():
            return None
        else:
            columns[name] = values
    return columns


def _as_float(values: np.ndarray) -> np.ndarray | None:
    """Text values as float64, or None when one is not a number."""
    try:
        return values.astype(float)
    except ValueError:
        return None


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
            if name in NUMERIC_COLUMNS:
                raise
            # extra non-numeric column: keep as text
            columns[name] = np.array(cols_text[j], dtype=object)
    return columns, len(rows)


# Magnitudes no real value reaches: a larger one is a unit or logging error, not data (1e300 dBm
# gave NaN).
_ABS_LIMITS = {"alt_m": 20000.0, "rel_alt_m": 20000.0}


def _validated(
    columns: dict[str, np.ndarray],
    path: Path,
    src: str,
    notes: list[str] | None = None,
    origin: Origin | None = None,
) -> FlightLog:
    """Check time order, units and ranges; attach the sidecar; drop repeated timestamps with a
    note."""
    notes = [] if notes is None else notes
    t = columns["t_s"]
    bad = np.flatnonzero(np.diff(t) < 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(
            f"time goes backwards ({t[i - 1]} then {t[i]})", source=src, row=i + 2, field="t_s"
        )
    lat, lon = columns["lat_deg"], columns["lon_deg"]
    for name, arr, lim in (("lat_deg", lat, 90.0), ("lon_deg", lon, 180.0)):
        badv = np.flatnonzero(np.abs(arr) > lim)
        if badv.size:
            raise InputError(
                f"{arr[badv[0]]} is outside +-{lim} degrees (wrong units?)",
                source=src,
                row=int(badv[0]) + 2,
                field=name,
            )
    for name, lim in (("roll_deg", 180.0), ("pitch_deg", 180.0), ("yaw_deg", 3600.0)):
        badv = np.flatnonzero(np.abs(np.nan_to_num(columns[name])) > lim)
        if badv.size:
            raise InputError(
                f"{columns[name][badv[0]]:g} is outside +-{lim:g} degrees (radians given?)",
                source=src,
                row=int(badv[0]) + 2,
                field=name,
            )
    lo, hi = RSS_RANGE_DB
    badv = np.flatnonzero(
        ~((columns["rss_dbm"] >= lo) & (columns["rss_dbm"] <= hi)) & ~np.isnan(columns["rss_dbm"])
    )
    if badv.size:
        raise InputError(
            f"{columns['rss_dbm'][badv[0]]:g} dB is not a plausible receiver reading "
            f"(expected {lo:g}..{hi:g})",
            source=src,
            row=int(badv[0]) + 2,
            field="rss_dbm",
        )
    for name, lim in _ABS_LIMITS.items():
        badv = np.flatnonzero(np.abs(columns[name]) > lim)
        if badv.size:
            raise InputError(
                f"{columns[name][badv[0]]:g} is not a plausible value (|value| > {lim:g})",
                source=src,
                row=int(badv[0]) + 2,
                field=name,
            )
    meta = _read_sidecar(path, notes, origin_given=origin is not None)
    if origin is not None:
        if "origin" in meta:
            notes.append("the origin given replaces the sidecar's")
        meta["origin"] = origin.to_dict()
    problem = latlon_unit_problem(
        lat, lon, Origin.from_dict(meta["origin"]) if "origin" in meta else None
    )
    if problem:
        raise InputError(problem[1], source=src, row=problem[0] + 2, field="lat_deg")
    dup = np.diff(t) == 0
    if dup.any():
        keep = np.concatenate([[True], ~dup])
        columns = {k: v[keep] for k, v in columns.items()}
        notes.append(
            f"dropped {int(dup.sum())} row(s) whose time repeats the previous row's (first kept), "
            f"e.g. row {int(np.argmax(dup)) + 3}"
        )
    n = len(columns["t_s"])
    if n < 2:
        raise InputError(f"only {n} data row; a flight log needs at least 2", source=src)
    return FlightLog(columns, meta, path, notes)


MAX_SIDECAR_BYTES = (
    10_000_000  # a sidecar with every live estimate of a long flight is well under 1 MB
)

# The sidecar keys the readers use, with the JSON types they expect (dotted: a key inside an
# object). A value of another type (a string where an object belongs) reached the user as an
# AttributeError.
SIDECAR_TYPES: dict[str, tuple[type, ...]] = {
    "format": (str,),
    "status": (str,),
    "mission": (str,),
    "mission_file": (str,),
    "rows": (int,),
    "rss_source": (dict,),
    "rss_source.kind": (str,),
    "rss_source.model": (str,),
    "rss_source.seed": (int,),
    "rss_source.model_params": (dict,),
    "trajectory": (dict,),
    "trajectory.generator": (str,),
    "trajectory.params": (dict,),
    "trajectory.altitude_m": (int, float),
    "trajectory.adaptive": (bool, dict, str),
    "live_estimate": (dict,),
    "live_estimate.method": (str,),
    "rover_area": (list,),
    "budget": (dict,),
    "adaptive": (dict,),
    "final_estimate": (dict,),
    "fast_estimate": (dict,),
    "estimates": (list,),
}


# A log whose sidecar still says "flying": fly-mission was killed outright (SIGKILL, power) before
# it closed it (one note line within 80 columns with the WARNING prefix).
ENDED_OPEN = "the log ended without closing (sidecar status 'flying')"


def _read_sidecar(path: Path, notes: list[str], origin_given: bool = False) -> dict:
    """The sidecar's metadata, its origin and truth checked (an InputError names the sidecar and
    key)."""
    sc = sidecar_path(path)
    if not sc.exists():
        where = (
            "the origin given"
            if origin_given
            else "its origin at the first sample (give --origin LAT,LON[,ALT] for the "
            "mission's frame)"
        )
        notes.append(
            f"{WARNING}no sidecar {sc.name}: read as an uncalibrated receiver log with {where} "
            "and no truth"
        )
        return {}

    try:
        meta = json.loads(read_text(sc, "sidecar", max_bytes=MAX_SIDECAR_BYTES))
    except json.JSONDecodeError as e:
        raise InputError(
            f"sidecar is not valid JSON ({e.msg} at line {e.lineno})", source=str(sc)
        ) from None
    except RecursionError:
        raise InputError("sidecar nested too deeply to be a flight log's", source=str(sc)) from None
    if not isinstance(meta, dict):
        raise InputError(
            f"sidecar must be a JSON object, got {type(meta).__name__}", source=str(sc)
        )
    check_types(meta, SIDECAR_TYPES, str(sc))
    if meta.get("origin") is not None:
        o = Fields(meta["origin"], str(sc), "origin", shape="{lat_deg, lon_deg, alt_m}")
        o.num("lat_deg", lo=-90.0, hi=90.0)
        o.num("lon_deg", lo=-180.0, hi=180.0)
        o.num("alt_m", None, -_ABS_LIMITS["alt_m"], _ABS_LIMITS["alt_m"])
    if meta.get("truth"):
        t = Fields(
            meta["truth"], str(sc), "truth", shape="{lat_deg, lon_deg, height_m} or {x_m, y_m, z_m}"
        )
        if "x_m" in t.d:
            for k in ("x_m", "y_m"):
                t.num(k, lo=-1e6, hi=1e6)
            t.num("z_m", None, -1e6, 1e6)
        else:
            t.num("lat_deg", lo=-90.0, hi=90.0)
            t.num("lon_deg", lo=-180.0, hi=180.0)
        for k in ("z_m", "height_m"):
            h = t.num(k, None, -1e4, 1e4)
            if h is not None and h < 0:
                raise t.err(k, f"transmitter below ground ({h:g} m)")
    status = meta.get("status")
    if status == "flying":  # the writer opens the sidecar so and closes it; killed, it stays
        notes.append(f"{WARNING}{ENDED_OPEN}: read as it is")
    elif status is not None and status != "completed":
        notes.append(
            f"{WARNING}the sidecar says the flight did not complete (status {status!r}): the "
            "log may end "
            "early or miss part of the pattern"
        )
    return meta
