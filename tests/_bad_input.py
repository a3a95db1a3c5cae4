"""Helpers of the bad-input suite: run a CLI in-process and check the project's promise on what it
printed.

The promise (README): bad input gives exit code 2 and exactly one line on stderr naming the file,
row or field, never a traceback; real-log quirks are accepted with a note.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from mission.flightlog import make_meta, write_flight_log
from mission.geo import afar_field

REPO = Path(__file__).resolve().parents[1]
SPIRAL = str(REPO / "missions" / "spiral.yaml")


def run_cli(
    main: Callable[[Sequence[str]], int], argv: Sequence[str], capsys
) -> tuple[int, str, str]:
    """Call a console-script ``main(argv)``; argparse's SystemExit counts as its return code."""
    capsys.readouterr()
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:
        rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    out, err = capsys.readouterr()
    return int(rc), out, err


def assert_refused(rc: int, err: str, *names: str) -> None:
    """Exit 2, one stderr line, no traceback, and every one of ``names`` (file, row, field) in that
    line."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err, err
    assert rc == 2, f"exit {rc}, stderr: {err}"
    assert len(lines) == 1, f"expected one stderr line, got {len(lines)}: {err}"
    for n in names:
        assert n in lines[0], f"{n!r} not named in: {lines[0]}"


def assert_accepted(rc: int, err: str, note: str | None = None) -> None:
    """Exit 0, no traceback or Python warning, and (when given) the note among stderr's note/warning
    lines."""
    assert "Traceback" not in err and "Warning:" not in err, err
    assert rc == 0, f"exit {rc}, stderr: {err}"
    if note is not None:
        notes = [ln for ln in err.splitlines() if ln.startswith(("note: ", "warning: "))]
        assert any(note in n for n in notes), f"note {note!r} not in {notes}"


def write_log(path: Path, n: int = 900, seed: int = 0, truth: bool = True) -> Path:
    """A small simulated-looking flight log (lawnmower at 30 m over the AFAR field, log-distance
    RSS) with its sidecar; rows are 0.1 s apart so that every row number in a test is a real line of
    the file."""
    rng = np.random.default_rng(seed)
    fld = afar_field()
    o = fld.origin
    s = np.linspace(0.0, 6.0, n)
    lane = np.floor(s)
    x = np.where(lane % 2 == 0, 30 + (s - lane) * 220, 250 - (s - lane) * 220)
    y = 20 + lane * 40
    z = np.full(n, 30.0)
    enu = np.column_stack([x, y, z])
    tx = np.array([150.0, 120.0, 1.5])
    rss = 30 - 20 * np.log10(np.linalg.norm(enu - tx, axis=1)) + rng.normal(0, 1, n)
    lat, lon, alt = o.to_geodetic(enu)
    cols = {
        "t_s": np.arange(n) * 0.1,
        "lat_deg": lat,
        "lon_deg": lon,
        "alt_m": alt,
        "rel_alt_m": z,
        "roll_deg": np.zeros(n),
        "pitch_deg": np.zeros(n),
        "yaw_deg": np.full(n, 90.0),
        "rss_dbm": rss,
    }
    tlat, tlon, _ = o.to_geodetic(tx)
    tr = {"lat_deg": float(tlat), "lon_deg": float(tlon), "height_m": 1.5} if truth else None
    return write_flight_log(
        path, cols, make_meta(o, {"kind": "sim", "model": "log-distance", "seed": seed}, tr)
    )


def mat_arrays(n: int = 300) -> dict[str, np.ndarray]:
    """The variables of a good AFAR MAT file (``rfsl import afar-mat``): n samples 0.1 s apart at 30
    m."""
    t = 1.7e9 + np.arange(n) * 0.1
    return {
        "timestamp_power": t,
        "mX": np.full(n, -78.698),
        "mY": 35.728 + np.linspace(0, 1e-3, n),
        "mZ": np.full(n, 30.0),
        "mRoll": np.zeros(n),
        "mPitch": np.zeros(n),
        "mYaw": np.zeros(n),
        "mpower": np.full(n, -50.0),
        "mquality": np.full(n, 70.0),
    }
