"""Writing flight logs: vectorised CSV rows with fixed digits per column, a crash-safe appending
writer.

Why here: the digits a column is written with are part of the format (``rounded`` gives a value
exactly as it will be read back, so what a simulated source used is what the log holds).
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.files import write_text, writing
from mission.flightlog.schema import COLUMNS, sidecar_path


def _fmt(a: np.ndarray, digits: int) -> np.ndarray:
    s = np.char.mod(f"%.{digits}f", a)
    return np.where(np.isnan(a), "", s)


DIGITS = {
    "t_s": 4,
    "lat_deg": 9,
    "lon_deg": 9,
    "alt_m": 3,
    "rel_alt_m": 3,
    "roll_deg": 3,
    "pitch_deg": 3,
    "yaw_deg": 3,
    "rss_dbm": 4,
    "mission_item": 0,
    "rss_quality_db": 2,
}
DEFAULT_DIGITS = 6


def rounded(values, column: str) -> np.ndarray:
    """``values`` rounded exactly as the log writes ``column`` (decimal text read back): logged ==
    used."""
    return np.char.mod(
        f"%.{DIGITS.get(column, DEFAULT_DIGITS)}f", np.asarray(values, dtype=float)
    ).astype(float)


def format_rows(columns: dict[str, np.ndarray], header: tuple[str, ...]) -> str:
    """CSV text (no header) for column arrays, vectorised; NaN becomes an empty field.

    Numeric columns get the digits of ``DIGITS``; text columns (str/object arrays such as ``phase``)
    are written as they are and must not contain commas, quotes or newlines.
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
    """Appends rows to a flight log and flushes them to disk, so a crash loses at most the unflushed
    rows.

    The sidecar is written when the writer opens (so a log is never without its metadata), updated
    in flight (``update_meta``) and rewritten by ``close`` (with ``meta_updates`` such as the end
    status).  A failed write (a full disk, a file-size limit: ``OSError``) is raised once and leaves
    the CSV cut back to the rows last flushed whole (``rows``, ``error``); later appends are
    dropped, so the sidecar's ``rows`` matches the file.
    """

    def __init__(self, path: str | Path, meta: dict, extra_columns: tuple[str, ...] = ()) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise InputError("refusing to overwrite an existing flight log", source=str(self.path))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.header = COLUMNS + tuple(extra_columns)
        self.meta = dict(meta)
        self.rows = 0
        self.error: OSError | None = None
        self._closed = False
        self._f = open(self.path, "w", newline="")
        self._good = (0, 0)  # (bytes, rows) on disk at the last whole flush
        self._f.write(",".join(self.header) + "\n")
        self._write_sidecar()
        self.flush()

    def _write_sidecar(self) -> None:
        tmp = sidecar_path(self.path).with_suffix(".json.tmp")
        tmp.write_text(json.dumps(self.meta, indent=2, default=float))
        os.replace(tmp, sidecar_path(self.path))

    def update_meta(self, **updates) -> None:
        """Update the sidecar now (an in-flight record such as the live estimates, the status),
        written whole (temporary name, then rename), so a crash or an abort keeps what was recorded
        so far."""
        self.meta.update(updates)
        self._write_sidecar()

    def append(self, columns: dict[str, np.ndarray]) -> None:
        """Append rows given as column arrays (missing optional columns are written empty)."""
        if self.error is not None:
            return  # the log failed: nothing more is written to it
        text = format_rows(columns, self.header)
        try:
            self._f.write(text)
        except OSError as e:
            self._fail(e)
            raise
        self.rows += len(columns["t_s"])

    def flush(self) -> None:
        if self.error is not None:
            return
        try:
            self._f.flush()
            os.fsync(self._f.fileno())
        except OSError as e:
            self._fail(e)
            raise
        self._good = (self._f.tell(), self.rows)

    def _fail(self, e: OSError) -> None:
        """Stop writing rows: the file cut back to its last whole flush (no partial line), ``rows``
        to match."""
        self.error = e
        size, self.rows = self._good
        with contextlib.suppress(OSError, ValueError):
            # its buffer cannot be written either; the descriptor is closed regardless
            self._f.close()
        with contextlib.suppress(OSError):
            os.truncate(self.path, size)

    def close(self, **meta_updates) -> None:
        """Flush and close the CSV, then write the sidecar with ``meta_updates`` and the row
        count."""
        if self._closed:
            return
        self._closed = True
        if self.error is None:
            try:
                self.flush()
            except OSError:
                pass  # recorded in ``error``; the sidecar below says how many rows the file holds
            with contextlib.suppress(OSError, ValueError):
                self._f.close()
        self.meta.update(meta_updates)
        self.meta["rows"] = self.rows
        self._write_sidecar()

    def __enter__(self) -> FlightLogWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_flight_log(
    path: str | Path, columns: dict[str, np.ndarray], meta: dict, overwrite: bool = False
) -> Path:
    """Write a whole log (CSV + sidecar) at once, e.g. from the simulator; columns beyond
    ``COLUMNS`` (such as ``PHASE_COLUMNS``) are written after them in the dict's order.

    Both files are written whole or not at all (``mission.files.writing``): a full disk leaves
    neither a truncated CSV beside a sidecar nor a sidecar alone.  An existing log (CSV or sidecar)
    is refused unless ``overwrite``."""
    path = Path(path)
    side = sidecar_path(path)
    if not overwrite:
        for p in (path, side):
            if p.exists():
                raise InputError("refusing to overwrite an existing flight log", source=str(p))
    header = COLUMNS + tuple(c for c in columns if c not in COLUMNS)
    meta = {**meta, "rows": len(columns["t_s"])}
    text = ",".join(header) + "\n" + format_rows(columns, header)
    had_side = side.exists()
    try:
        with writing(path) as tmp:
            tmp.write_text(text)
            write_text(side, json.dumps(meta, indent=2, default=float))
    except BaseException:
        if not had_side:  # the CSV did not land: a sidecar of ours must not stand alone
            side.unlink(missing_ok=True)
        raise
    return path
