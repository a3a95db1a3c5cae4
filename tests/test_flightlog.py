"""Flight-log format: round trip, validation errors naming file/row/column, crash safety of the
writer."""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys

import numpy as np
import pytest

from mission.errors import InputError
from mission.flightlog import (
    COLUMNS,
    FlightLogWriter,
    format_rows,
    make_meta,
    read_flight_log,
    sidecar_path,
    write_flight_log,
)
from mission.flightlog.read import _fast_parse, _slow_parse
from mission.flightlog.schema import QUALITY_COLUMN, lock_floor_db
from mission.geo import Origin

O = Origin(35.727, -78.698, 90.0)


def _cols(n=50, attitude=True):
    t = np.arange(n) * 0.03
    enu = np.stack([np.linspace(0, 100, n), np.linspace(0, 50, n), np.full(n, 30.0)], axis=1)
    lat, lon, alt = O.to_geodetic(enu)
    c = {
        "t_s": t,
        "lat_deg": lat,
        "lon_deg": lon,
        "alt_m": alt,
        "rel_alt_m": enu[:, 2],
        "rss_dbm": -60 + np.sin(t),
    }
    if attitude:
        c.update(roll_deg=np.full(n, 1.5), pitch_deg=np.full(n, -3.0), yaw_deg=np.full(n, 90.0))
    return c, enu


def test_round_trip(tmp_path):
    c, enu = _cols()
    meta = make_meta(
        O, {"kind": "sim", "model": "e2r", "seed": 4}, truth={"x_m": 10, "y_m": 20, "z_m": 1.5}
    )
    p = write_flight_log(tmp_path / "f.csv", c, meta)
    log = read_flight_log(p)
    assert len(log) == 50
    assert np.allclose(log["rss_dbm"], c["rss_dbm"], atol=1e-4)
    assert np.allclose(log.enu(), enu, atol=0.01)
    assert np.allclose(np.rad2deg(log.attitude_rad[:, 2]), 90.0)
    assert log.meta["rss_source"]["seed"] == 4
    assert np.allclose(log.truth_enu, [10, 20, 1.5])
    assert log.origin == O


def test_receiver_only_log_has_no_attitude(tmp_path):
    c, _ = _cols(attitude=False)
    p = write_flight_log(tmp_path / "f.csv", c, make_meta(O, {"kind": "real"}))
    log = read_flight_log(p)
    assert log.attitude_rad is None
    assert ",," in p.read_text().splitlines()[1]


def test_extra_columns_are_kept(tmp_path):
    p = tmp_path / "x.csv"
    p.write_text(
        "t_s,lat_deg,lon_deg,alt_m,rel_alt_m,rss_dbm,quality_db,note\n"
        "0,35.7,-78.7,120,30,-50,40,a\n0.03,35.7,-78.7,120,30,-51,41,b\n"
    )
    log = read_flight_log(p)
    assert log["quality_db"].tolist() == [40, 41]
    assert log["note"].tolist() == ["a", "b"]


@pytest.mark.parametrize(
    "mutate, expect",
    [
        (
            lambda L: [L[0].replace(",rss_dbm", "")] + [r.rsplit(",", 1)[0] for r in L[1:]],
            r"missing required column\(s\) rss_dbm",
        ),
        (
            lambda L: L[:3] + [L[3].replace(L[3].split(",")[-1], "nan")] + L[4:],
            r"row 4, field 'rss_dbm': NaN",
        ),
        (
            lambda L: L[:2] + [L[2].replace(L[2].split(",")[-1], "abc")] + L[3:],
            r"row 3, field 'rss_dbm': not a number",
        ),
        (
            lambda L: L[:5] + [L[5].replace(L[5].split(",")[0], "0.0000", 1)] + L[6:],
            r"row 6, field 't_s': time goes backwards",
        ),
        (lambda L: L[:2] + [L[2] + ",9"] + L[3:], r"row 3: expected 9 fields, found 10"),
        (lambda L: L[:1], "no data rows"),
    ],
)
def test_validation_errors_name_file_row_and_column(tmp_path, mutate, expect):
    c, _ = _cols()
    p = write_flight_log(tmp_path / "f.csv", c, make_meta(O, {"kind": "sim"}))
    lines = p.read_text().splitlines()
    p.write_text("\n".join(mutate(lines)) + "\n")
    with pytest.raises(InputError, match=expect) as ei:
        read_flight_log(p)
    assert str(p) in str(ei.value)


def test_wrong_units_radians_and_bad_latitude(tmp_path):
    c, _ = _cols()
    c["lat_deg"] = c["lat_deg"] * 1e7  # MAVLink integer degrees given as degrees
    p = write_flight_log(tmp_path / "a.csv", c, make_meta(O, {"kind": "sim"}))
    with pytest.raises(InputError, match="lat_deg.*wrong units"):
        read_flight_log(p)


def test_writer_is_readable_before_close_and_never_overwrites(tmp_path):
    c, _ = _cols(100)
    w = FlightLogWriter(tmp_path / "live.csv", make_meta(O, {"kind": "sim"}))
    w.append({k: v[:60] for k, v in c.items()})
    w.flush()
    # a crash now (no close) still leaves a readable log with its sidecar
    log = read_flight_log(tmp_path / "live.csv")
    assert len(log) == 60 and log.meta["rss_source"]["kind"] == "sim"
    w.append({k: v[60:] for k, v in c.items()})
    w.close(status="completed")
    assert json.loads(sidecar_path(tmp_path / "live.csv").read_text())["status"] == "completed"
    assert len(read_flight_log(tmp_path / "live.csv")) == 100
    with pytest.raises(InputError, match="overwrite"):
        FlightLogWriter(tmp_path / "live.csv", {})


def test_missing_file_and_bad_sidecar(tmp_path):
    with pytest.raises(InputError, match="no such flight log"):
        read_flight_log(tmp_path / "nope.csv")
    c, _ = _cols()
    p = write_flight_log(tmp_path / "f.csv", c, make_meta(O, {"kind": "sim"}))
    sidecar_path(p).write_text("{not json")
    with pytest.raises(InputError, match="sidecar is not valid JSON"):
        read_flight_log(p)


def _phase_log_text(n: int = 6) -> list[str]:
    """A small log with the text ``phase`` column, as CSV lines (header first)."""
    c, _ = _cols(n)
    c["phase"] = np.array(["takeoff", "mission", "mission", "mission", "return", "land"][:n])
    c["mission_item"] = np.array([-1, 0, 1, 2, -1, -1][:n], dtype=float)

    header = COLUMNS + ("phase", "mission_item")
    return [",".join(header)] + format_rows(c, header).splitlines()


def test_phase_log_parsed_in_one_pass_as_the_row_parser_would(tmp_path):
    """The vectorised reader keeps ``phase`` as text and agrees with the row-by-row parser on odd
    fields (an empty phase, a blank padded with spaces in an extra numeric column)."""
    lines = _phase_log_text()
    rows = [ln.split(",") for ln in lines]
    rows[2][-2] = ""  # phase left empty on data row 2
    rows[3][-1] = "  "  # mission_item blank with spaces on data row 3
    text = "\n".join(",".join(r) for r in rows) + "\n"
    header = rows[0]
    fast = _fast_parse(text, header)
    reader = csv.reader(io.StringIO(text))
    next(reader)
    slow, _ = _slow_parse(reader, header, "x")
    assert fast is not None and list(fast) == list(slow)
    for k in slow:
        assert fast[k].dtype == slow[k].dtype, k
        if slow[k].dtype == object:
            assert fast[k].tolist() == slow[k].tolist()
        else:
            assert np.array_equal(fast[k], slow[k], equal_nan=True), k
    assert fast["phase"].tolist()[:3] == ["takeoff", "", "mission"] and np.isnan(
        fast["mission_item"][2]
    )
    p = tmp_path / "p.csv"
    p.write_text(text)
    assert read_flight_log(p)["phase"].tolist()[2] == "mission"


def test_phase_log_with_a_bad_number_names_its_row(tmp_path):
    """A bad value in a format column of a phase log still reaches the row-by-row parser's
    message."""
    lines = _phase_log_text()
    rows = [ln.split(",") for ln in lines]
    rows[3][rows[0].index("rss_dbm")] = "-6x.5"
    p = tmp_path / "bad.csv"
    p.write_text("\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(InputError) as e:
        read_flight_log(p)
    assert e.value.row == 4 and e.value.field == "rss_dbm" and "not a number" in str(e.value)


def test_samples_view_of_a_log(tmp_path):
    """``FlightLog.samples()``: positions, radians, the phase and the truth in the log's frame;
    ``select`` cuts every per-sample array and keeps the rest."""
    lines = _phase_log_text()
    p = tmp_path / "s.csv"
    p.write_text("\n".join(lines) + "\n")
    sidecar_path(p).write_text(
        json.dumps(make_meta(O, {"kind": "sim"}, truth={"x_m": 10, "y_m": 20, "z_m": 1.5}))
    )
    log = read_flight_log(p)
    s = log.samples()
    assert len(s) == 6 and s.name == "s" and np.allclose(s.tx_enu_m, [10, 20, 1.5])
    assert np.allclose(s.enu_m, log.enu()) and np.allclose(np.rad2deg(s.attitude_rad[:, 0]), 1.5)
    assert s.phase.tolist() == log["phase"].tolist()
    m = s.select(s.phase == "mission")
    assert (
        len(m) == 3 and m.t_s.shape == (3,) and m.enu_m.shape == (3, 3) and m.tx_enu_m is s.tx_enu_m
    )
    # the sidecar's truth is in its own frame
    assert log.samples(Origin(35.7, -78.7, 90.0)).tx_enu_m is None


_FULL_DISK = """
import resource, signal, sys
import numpy as np
from mission.flightlog import FlightLogWriter, make_meta
from mission.geo import Origin

signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the limit gives EFBIG, as a full disk gives ENOSPC
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]), int(sys.argv[2])))
n = 40
t = np.arange(n) * 0.03
c = {"t_s": t, "lat_deg": np.full(n, 35.7), "lon_deg": np.full(n, -78.7),
     "alt_m": np.full(n, 120.0), "rel_alt_m": np.full(n, 30.0), "rss_dbm": -60.0 + t}
w = FlightLogWriter(sys.argv[1], make_meta(Origin(35.727, -78.698, 90.0), {"kind": "sim"}))
failed = None
for k in range(200):
    try:
        w.append({key: v + (k * n * 0.03 if key == "t_s" else 0) for key, v in c.items()})
        w.flush()
    except OSError as e:
        failed = k
        break
w.append(c)  # after a failure: dropped, never a partial line
w.close(status="flying on")
print(failed, w.rows, type(w.error).__name__)
"""


@pytest.mark.parametrize("limit", [3000, 20000, 20011])
def test_a_failed_write_leaves_whole_rows_and_a_matching_sidecar(tmp_path, limit):
    """A file-size limit (as a full disk) mid-log: the writer raises once, the CSV is cut back to
    the rows last flushed whole (no partial line, whatever byte the limit falls on), later rows are
    dropped and the sidecar's ``rows`` is what the file holds."""
    path = tmp_path / "f.csv"
    r = subprocess.run(
        [sys.executable, "-c", _FULL_DISK, str(path), str(limit)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    failed, rows, error = r.stdout.split()
    assert failed != "None" and error == "OSError" and int(rows) == 40 * int(failed)
    log = read_flight_log(path)
    assert len(log) == int(rows) == log.meta["rows"] and log.meta["status"] == "flying on"
    assert path.stat().st_size <= limit and path.read_text().endswith("\n")
    assert np.all(np.diff(log["t_s"]) > 0)


def test_the_receivers_quality_column_holds_numbers_or_nothing(tmp_path):
    """``rss_quality_db`` (``NUMERIC_COLUMNS``): an empty value reads as NaN (out of lock); a text
    is a broken row, named, as in a format column, while another extra column may hold text."""
    c, _ = _cols(6)
    q = np.array([72.0, np.nan, 45.0, 70.0, 71.0, 72.0])
    p = write_flight_log(tmp_path / "q.csv", {**c, QUALITY_COLUMN: q}, make_meta(O, {"kind": "x"}))
    log = read_flight_log(p)
    assert np.isnan(log[QUALITY_COLUMN][1]) and log[QUALITY_COLUMN][2] == 45.0
    lines = p.read_text().splitlines()
    lines[4] = lines[4].rsplit(",", 1)[0] + ",locked"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=rf"row 5, field '{QUALITY_COLUMN}': not a number"):
        read_flight_log(p)


def test_lock_floor_is_where_lock_comes_and_goes():
    """``lock_floor_db``: a receiver that holds lock exactly while the power is above -20 dB, the
    power sweeping down and up through it with noise, gives -20 dB within the sweep's step; the
    locked row next to each change is used (a loss and a regain at the same level: no hysteresis
    in the data, none in the figure); no change of state gives None."""
    rng = np.random.default_rng(3)
    p = np.r_[np.linspace(0, -40, 400), np.linspace(-40, 0, 400)] + rng.normal(0, 1.0, 800)
    q = np.where(p >= -20.0, p + 72.0, 44.0)
    f = lock_floor_db(p, q)
    assert f is not None and -20.0 <= f < -18.5
    # NaN quality counts as out of lock; NaN power at an edge is skipped
    q2 = q.copy()
    q2[:5] = np.nan
    assert lock_floor_db(p, q2) == pytest.approx(f, abs=1.0)
    assert lock_floor_db(p, np.full(800, 72.0)) is None
    assert lock_floor_db(p, np.full(800, 40.0)) is None
    assert lock_floor_db(np.array([]), np.array([])) is None
