"""Bad flight logs and sidecars through every command that reads a log: each is refused with exit 2
and one line naming the file, row and field, or, for a real-log quirk, accepted with its note.

Every case runs through ``read_flight_log`` and the CLIs that read logs (``localize``, ``rfsl
replay``, ``rfsl gap``, ``rfsl evaluate --real``), in-process.  Hypothesis generates further
corruptions.
"""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from _bad_input import assert_accepted, assert_refused, run_cli, write_log
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mission.cli.localize import main as localize_main
from mission.cli.main import main as rfsl_main
from mission.errors import InputError
from mission.flightlog import COLUMNS, read_flight_log, sidecar_path

COL = {c: i for i, c in enumerate(COLUMNS)}
HYPO = settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


class _Base(tuple):
    """(CSV text, sidecar dict) of the good log; a short repr keeps hypothesis' reports readable."""

    def __repr__(self) -> str:
        return "<good 900-row log>"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A good log (CSV text, sidecar dict) every case mutates."""
    p = write_log(tmp_path_factory.mktemp("base") / "flight.csv")
    return _Base((p.read_text(), json.loads(sidecar_path(p).read_text())))


def _cell(lines: list[str], row: int, col: str, value: str) -> list[str]:
    """Lines with the field ``col`` of file row ``row`` (header = row 1) replaced by ``value``."""
    out = list(lines)
    f = out[row - 1].split(",")
    f[COL[col]] = value
    out[row - 1] = ",".join(f)
    return out


def _column(lines: list[str], col: str, fn) -> list[str]:
    """Lines with every value of ``col`` replaced by ``fn(float)``."""
    out = [lines[0]]
    for ln in lines[1:]:
        f = ln.split(",")
        f[COL[col]] = repr(fn(float(f[COL[col]])))
        out.append(",".join(f))
    return out


def _backwards(lines: list[str], row: int) -> list[str]:
    return _cell(lines, row, "t_s", "0.0")


# name -> (CSV mutation on the list of lines, substrings the error line must hold besides the file)
CSV_REFUSED = {
    "nan rss": (lambda L: _cell(L, 10, "rss_dbm", "nan"), ["row 10", "'rss_dbm'"]),
    "empty rss": (lambda L: _cell(L, 11, "rss_dbm", ""), ["row 11", "'rss_dbm'"]),
    "text latitude": (
        lambda L: _cell(L, 12, "lat_deg", "abc"),
        ["row 12", "'lat_deg'", "not a number"],
    ),
    "inf altitude": (lambda L: _cell(L, 15, "alt_m", "inf"), ["row 15", "'alt_m'"]),
    "-inf time": (lambda L: _cell(L, 20, "t_s", "-inf"), ["row 20", "'t_s'"]),
    "rss 1e300": (lambda L: _cell(L, 30, "rss_dbm", "1e300"), ["row 30", "'rss_dbm'", "plausible"]),
    "rss -1e5": (lambda L: _cell(L, 31, "rss_dbm", "-100000"), ["row 31", "'rss_dbm'"]),
    "altitude 1e7": (lambda L: _cell(L, 40, "alt_m", "1e7"), ["row 40", "'alt_m'"]),
    "relative altitude in mm": (
        lambda L: _column(L, "rel_alt_m", lambda v: v * 1000),
        ["row 2", "'rel_alt_m'"],
    ),
    "latitude 95": (
        lambda L: _cell(L, 50, "lat_deg", "95.0"),
        ["row 50", "'lat_deg'", "wrong units"],
    ),
    "longitude -200": (lambda L: _cell(L, 51, "lon_deg", "-200.0"), ["row 51", "'lon_deg'"]),
    "latitude 1e7 scaled": (
        lambda L: _column(L, "lat_deg", lambda v: v * 1e7),
        ["'lat_deg'", "wrong units"],
    ),
    "roll 200": (lambda L: _cell(L, 60, "roll_deg", "200"), ["row 60", "'roll_deg'", "radians"]),
    "pitch -500": (lambda L: _cell(L, 61, "pitch_deg", "-500"), ["row 61", "'pitch_deg'"]),
    "time backwards": (lambda L: _backwards(L, 70), ["row 70", "'t_s'", "backwards"]),
    "time backwards late": (lambda L: _backwards(L, 700), ["row 700", "'t_s'", "backwards"]),
    "extra field mid-file": (lambda L: L[:79] + [L[79] + ",9"] + L[80:], ["row 80", "fields"]),
    "missing field mid-file": (
        lambda L: L[:80] + [L[80].rsplit(",", 1)[0]] + L[81:],
        ["row 81", "fields"],
    ),
    "cut row mid-file": (lambda L: L[:99] + [L[99][:12]] + L[100:], ["row 100", "fields"]),
    "empty time": (lambda L: _cell(L, 90, "t_s", ""), ["row 90", "'t_s'"]),
    "nan time": (lambda L: _cell(L, 5, "t_s", "nan"), ["row 5", "'t_s'"]),
    "missing rss column": (
        lambda L: [ln.rsplit(",", 1)[0] for ln in L],
        ["missing required column", "rss_dbm"],
    ),
    "missing time column": (
        lambda L: [ln.split(",", 1)[1] for ln in L],
        ["missing required column", "t_s"],
    ),
    "header only": (lambda L: L[:1], ["no data rows"]),
    "one row": (lambda L: L[:2], ["only 1 data row"]),
    "radians": (
        lambda L: _column(_column(L, "lat_deg", math.radians), "lon_deg", math.radians),
        ["row 2", "'lat_deg'", "radians"],
    ),
    "lat and lon swapped": (
        lambda L: (
            L[:1] + [",".join([f[0], f[2], f[1], *f[3:]]) for f in (ln.split(",") for ln in L[1:])]
        ),
        ["'lat_deg'", "km from the origin"],
    ),
    "semicolon separated": (
        lambda L: [ln.replace(",", ";") for ln in L],
        ["missing required column"],
    ),
    "not text": (lambda L: b"\xff\xfe\x00\x81garbage", ["not a text CSV file"]),
    "empty file": (lambda L: "", ["empty file"]),
}

SIDECAR_REFUSED = {
    "invalid json": (lambda m: "{not json", ["flight.json", "not valid JSON"]),
    "json list": (lambda m: "[1, 2]", ["flight.json", "JSON object"]),
    "origin not a mapping": (lambda m: {**m, "origin": [35.7, -78.7]}, ["flight.json", "'origin'"]),
    "origin without lat": (lambda m: {**m, "origin": {"lon_deg": -78.7}}, ["'origin.lat_deg'"]),
    "origin lat text": (
        lambda m: {**m, "origin": {**m["origin"], "lat_deg": "35.7"}},
        ["'origin.lat_deg'"],
    ),
    "origin lat 200": (
        lambda m: {**m, "origin": {**m["origin"], "lat_deg": 200.0}},
        ["'origin.lat_deg'"],
    ),
    "origin lon NaN": (
        lambda m: {**m, "origin": {**m["origin"], "lon_deg": float("nan")}},
        ["'origin.lon_deg'"],
    ),
    "origin alt 1e9": (
        lambda m: {**m, "origin": {**m["origin"], "alt_m": 1e9}},
        ["'origin.alt_m'"],
    ),
    "origin far away": (
        lambda m: {**m, "origin": {"lat_deg": 0.0, "lon_deg": 0.0, "alt_m": 0.0}},
        ["'lat_deg'", "km from the origin"],
    ),
    "truth a list": (lambda m: {**m, "truth": [1, 2]}, ["'truth'"]),
    "truth lat text": (
        lambda m: {**m, "truth": {**m["truth"], "lat_deg": "x"}},
        ["'truth.lat_deg'"],
    ),
    "truth below ground": (
        lambda m: {**m, "truth": {**m["truth"], "height_m": -3.0}},
        ["'truth.height_m'", "below ground"],
    ),
    "truth x without y": (lambda m: {**m, "truth": {"x_m": 10.0}}, ["'truth.y_m'"]),
}

# name -> (CSV mutation, sidecar mutation or None, the note it must be accepted with)
ACCEPTED = {
    "repeated timestamp": (
        lambda L: _cell(L, 101, "t_s", L[99].split(",")[0]),
        None,
        "dropped 1 row(s)",
    ),
    "five repeated timestamps": (
        lambda L: [
            _cell(L, r, "t_s", L[r - 2].split(",")[0])[r - 1]
            if r in (50, 150, 250, 350, 450)
            else ln
            for r, ln in enumerate(L, start=1)
        ],
        None,
        "dropped 5 row(s)",
    ),
    "last line cut to a few fields": (
        lambda L: L[:-1] + [L[-1][:15]],
        None,
        "dropped the last line",
    ),
    "last line cut, rss missing": (
        lambda L: L[:-1] + [L[-1].rsplit(",", 1)[0] + ","],
        None,
        "dropped the last line",
    ),
    "last line cut without newline": (lambda L: "\n".join(L)[:-2], None, "no line end"),
    "no sidecar": (lambda L: L, "delete", "no sidecar flight.json"),
    "log left open (killed in flight)": (
        lambda L: L,
        lambda m: {**m, "status": "flying"},
        "ended without closing (sidecar status 'flying'): read as it is",
    ),
    "flight failed": (
        lambda L: L,
        lambda m: {**m, "status": "failed: link lost"},
        "'failed: link lost'",
    ),
    "windows line ends": (lambda L: "\r\n".join(L) + "\r\n", None, None),
    "byte-order mark": (lambda L: "\ufeff" + "\n".join(L) + "\n", None, None),
    "trailing blank lines": (lambda L: L + ["", "", ""], None, None),
    "extra text column": (lambda L: [L[0] + ",comment"] + [ln + ",ok" for ln in L[1:]], None, None),
    "receiver-only, no attitude": (
        lambda L: [
            ",".join(f[:5] + ["", "", ""] + f[8:]) if i else ln
            for i, (ln, f) in enumerate((ln, ln.split(",")) for ln in L)
        ],
        None,
        None,
    ),
}


def _make(tmp_path, base, csv_mut=None, side_mut=None):
    """Write the mutated log (flight.csv + flight.json) into ``tmp_path``; return the CSV path."""
    text, meta = base
    lines = text.splitlines()
    p = tmp_path / "flight.csv"
    new = csv_mut(lines) if csv_mut else lines
    if isinstance(new, bytes):
        p.write_bytes(new)
    else:
        p.write_bytes((new if isinstance(new, str) else "\n".join(new) + "\n").encode())
    sc = sidecar_path(p)
    if side_mut == "delete":
        return p
    m = side_mut(json.loads(json.dumps(meta))) if side_mut else meta
    sc.write_text(m if isinstance(m, str) else json.dumps(m))
    return p


ENTRY = {  # how each command is given a log (in-process main and argv)
    "localize": (localize_main, lambda p, tmp: [p, "--method", "centroid"]),
    "replay": (rfsl_main, lambda p, tmp: ["replay", p, "--out", tmp / "r.png"]),
    "gap": (rfsl_main, lambda p, tmp: ["gap", p, "--no-localize"]),
    "evaluate": (rfsl_main, lambda p, tmp: ["evaluate", "--real", p, "--methods", "centroid"]),
}


@pytest.mark.parametrize("entry", ["read", *ENTRY])
@pytest.mark.parametrize("case", list(CSV_REFUSED))
def test_bad_csv_is_refused(tmp_path, base, capsys, case, entry):
    mut, names = CSV_REFUSED[case]
    p = _make(tmp_path, base, mut)
    if entry == "read":
        with pytest.raises(InputError) as ei:
            read_flight_log(p)
        msg = str(ei.value)
        assert "\n" not in msg and str(p) in msg and all(n in msg for n in names), msg
        return
    main, argv = ENTRY[entry]
    rc, _, err = run_cli(main, argv(p, tmp_path), capsys)
    assert_refused(rc, err, str(p), *names)


@pytest.mark.parametrize("entry", ["read", "localize", "replay", "gap"])
@pytest.mark.parametrize("case", list(SIDECAR_REFUSED))
def test_bad_sidecar_is_refused(tmp_path, base, capsys, case, entry):
    mut, names = SIDECAR_REFUSED[case]
    p = _make(tmp_path, base, None, mut)
    if entry == "read":
        with pytest.raises(InputError) as ei:
            read_flight_log(p)
        assert all(n in str(ei.value) for n in names), str(ei.value)
        return
    main, argv = ENTRY[entry]
    rc, _, err = run_cli(main, argv(p, tmp_path), capsys)
    assert_refused(rc, err, *names)


@pytest.mark.parametrize("entry", ["read", "localize", "replay"])
@pytest.mark.parametrize("case", list(ACCEPTED))
def test_real_log_quirks_are_accepted_with_a_note(tmp_path, base, capsys, case, entry):
    csv_mut, side_mut, note = ACCEPTED[case]
    p = _make(tmp_path, base, csv_mut, side_mut)
    if entry == "read":
        log = read_flight_log(p)
        assert any(note in n for n in log.notes) if note else not log.notes, log.notes
        assert np.all(np.diff(log["t_s"]) > 0) and np.isfinite(log["rss_dbm"]).all()
        n_base = len(base[0].splitlines()) - 1
        assert n_base - 5 <= len(log) <= n_base  # only the quirky rows went
        return
    main, argv = ENTRY[entry]
    rc, _, err = run_cli(main, argv(p, tmp_path), capsys)
    assert_accepted(rc, err, note)


@pytest.mark.parametrize("entry", ["localize", "replay"])
def test_a_log_left_open_says_it_ended_without_closing_in_one_line(tmp_path, base, capsys, entry):
    """A sidecar still saying ``flying`` (fly-mission killed outright): one warning line within 80
    columns, and the rows are still localized or summarised."""
    p = _make(tmp_path, base, None, lambda m: {**m, "status": "flying"})
    main, argv = ENTRY[entry]
    rc, out, err = run_cli(main, argv(p, tmp_path), capsys)
    assert_accepted(rc, err)
    said = [ln for ln in err.splitlines() if "ended without closing" in ln]
    assert len(said) == 1 and said[0].startswith("warning: ") and len(said[0]) <= 80, said
    assert ("estimate" in out) if entry == "localize" else ("flying" in out), out


def test_localize_json_carries_the_notes(tmp_path, base, capsys):
    p = _make(tmp_path, base, ACCEPTED["repeated timestamp"][0], "delete")
    rc, out, err = run_cli(localize_main, [p, "--method", "centroid", "--json"], capsys)
    assert_accepted(rc, err, "no sidecar")
    notes = json.loads(out)["notes"]
    assert any("no sidecar" in n for n in notes) and any("dropped 1 row(s)" in n for n in notes)


def test_origin_option_places_a_sidecarless_log(tmp_path, base, capsys):
    """Without a sidecar the origin is the first sample (about 160 m off on AFAR); --origin puts it
    right."""
    good = _make(tmp_path, base)
    rc, out, _ = run_cli(localize_main, [good, "--method", "centroid", "--json"], capsys)
    ref = json.loads(out)
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(good, bare / "flight.csv")
    o = base[1]["origin"]
    rc, out, err = run_cli(
        localize_main,
        [
            bare / "flight.csv",
            "--method",
            "centroid",
            "--json",
            "--origin",
            f"{o['lat_deg']},{o['lon_deg']},{o['alt_m']}",
        ],
        capsys,
    )
    assert_accepted(rc, err, "no sidecar")
    d = json.loads(out)
    assert abs(d["x_m"] - ref["x_m"]) < 0.01 and abs(d["y_m"] - ref["y_m"]) < 0.01
    rc, out, err = run_cli(
        localize_main, [bare / "flight.csv", "--method", "centroid", "--json"], capsys
    )
    assert "origin at the first sample" in err and abs(json.loads(out)["x_m"] - ref["x_m"]) > 10


# --- generated with hypothesis
# -----------------------------------------------------------------------------

BAD_VALUES = {  # values no column accepts, and the words the error uses for them
    "nan": "NaN",
    "": "empty",
    "inf": "infinite",
    "-inf": "infinite",
    "abc": "not a number",
    "1,5": "fields",
    "--": "not a number",
    "0x1F": "not a number",
}


@HYPO
@given(
    row=st.integers(3, 800),
    col=st.sampled_from(["t_s", "lat_deg", "lon_deg", "alt_m", "rel_alt_m", "rss_dbm"]),
    value=st.sampled_from(sorted(BAD_VALUES)),
)
def test_generated_bad_cell_names_row_and_field(tmp_path_factory, base, row, col, value):
    p = _make(tmp_path_factory.mktemp("h"), base, lambda L: _cell(L, row, col, value))
    with pytest.raises(InputError) as ei:
        read_flight_log(p)
    msg = str(ei.value)
    assert f"row {row}" in msg and BAD_VALUES[value] in msg, msg
    if value != "1,5":
        assert f"'{col}'" in msg, msg


@HYPO
@given(
    row=st.integers(3, 899),
    col=st.sampled_from(["rss_dbm", "alt_m", "rel_alt_m"]),
    mag=st.floats(401, 1e300),
    sign=st.sampled_from([-1, 1]),
)
def test_generated_absurd_magnitude_is_refused(tmp_path_factory, base, row, col, mag, sign):
    v = sign * (mag if col == "rss_dbm" else mag * 50)  # altitudes: beyond 20 km
    p = _make(tmp_path_factory.mktemp("h"), base, lambda L: _cell(L, row, col, repr(v)))
    with pytest.raises(InputError, match=rf"row {row}, field '{col}': .*plausible"):
        read_flight_log(p)


@HYPO
@given(rows=st.sets(st.integers(3, 880), min_size=1, max_size=12))
def test_generated_repeated_timestamps_dropped_with_count(tmp_path_factory, base, rows):
    def mut(L):
        out = list(L)
        for r in sorted(rows):
            out = _cell(out, r, "t_s", out[r - 2].split(",")[0])
        return out

    # a repeat of a repeat (rows r and r+1 both chosen) is still one dropped row each
    log = read_flight_log(_make(tmp_path_factory.mktemp("h"), base, mut))
    assert len(log) == 900 - len(rows)
    assert any(f"dropped {len(rows)} row(s)" in n for n in log.notes), log.notes


@HYPO
@given(row=st.integers(3, 899), back=st.floats(0.01, 50))
def test_generated_time_going_backwards_is_refused(tmp_path_factory, base, row, back):
    def mut(L):
        t_prev = float(L[row - 2].split(",")[0])
        return _cell(L, row, "t_s", f"{t_prev - back:.4f}")

    with pytest.raises(InputError, match=rf"row {row}, field 't_s': time goes backwards"):
        read_flight_log(_make(tmp_path_factory.mktemp("h"), base, mut))


@HYPO
@given(cut=st.integers(1, 60))
def test_generated_crash_cut_last_line_is_dropped(tmp_path_factory, base, cut):
    text = base[0]
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    cut = min(cut, len(last) - 1)
    p = _make(tmp_path_factory.mktemp("h"), base, lambda L: text.rstrip("\n")[:-cut])
    log = read_flight_log(p)
    assert len(log) == 899 and any("dropped the last line (row 901)" in n for n in log.notes), (
        log.notes
    )


@HYPO
@given(
    scale=st.sampled_from([math.radians, lambda v: v / 1000.0, lambda v: v * 0.0174]),
    with_sidecar=st.booleans(),
)
def test_generated_wrong_angle_units_are_refused(tmp_path_factory, base, scale, with_sidecar):
    def mut(L):
        return _column(_column(L, "lat_deg", scale), "lon_deg", scale)

    p = _make(tmp_path_factory.mktemp("h"), base, mut, None if with_sidecar else "delete")
    with pytest.raises(InputError, match=r"field 'lat_deg'"):
        read_flight_log(p)
