"""Generated malformed inputs for every kind of file and option (issue 37's sweep as a suite):
hypothesis mutates a real sidecar, a real mission, a real MAT file and command-line options (types,
ranges, nesting, encodings, sizes) and asserts the promise on each: success, or exit 2 with exactly
one error line (besides the 'note:' / 'warning:' lines of what was accepted), never a traceback,
never a hang.

Slow tier, fixed seed (``derandomize=True``), a bounded number of examples, and each call under an
alarm (``CALL_LIMIT_S``): a case that hangs (a FIFO, a bomb) fails instead of stalling the suite.
The CLIs are called in-process (``main(argv)``) to keep it fast.  Option cases end in an output path
under a file, so a valid combination is refused at that path and nothing heavy (a flight, a dataset)
ever starts.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import signal
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio
import yaml
from _bad_input import SPIRAL, mat_arrays, write_log
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from mission.cli.fly import main as fly_main
from mission.cli.localize import main as localize_main
from mission.cli.main import main as rfsl_main

pytestmark = pytest.mark.slow

# no shrinking phase: the time stays bounded by max_examples (a failure prints its unshrunk case)
FUZZ = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    phases=[Phase.explicit, Phase.generate],
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
CALL_LIMIT_S = 60


class Hung(Exception):
    pass


def call(main, argv: list) -> tuple[int, str, str]:
    """``main(argv)`` with stdout/stderr captured and an alarm: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()

    def alarm(*_):
        raise Hung(f"{argv} ran past {CALL_LIMIT_S} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(CALL_LIMIT_S)
    try:
        with (
            contextlib.redirect_stdout(out),
            contextlib.redirect_stderr(err),
            warnings.catch_warnings(),
        ):
            warnings.simplefilter("ignore")
            try:
                rc = main([str(a) for a in argv])
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    return int(rc), out.getvalue(), err.getvalue()


def assert_promise(rc: int, err: str, argv) -> None:
    """Success, or exit 2 with one error line; never a traceback (any other exception fails the
    test)."""
    assert "Traceback" not in err, (argv, err)
    if rc == 0:
        return
    lines = [
        ln
        for ln in err.splitlines()
        if ln.strip() and not ln.startswith(("note: ", "warning: ", "  "))
    ]
    assert rc == 2, (argv, rc, err)
    assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)


# --- values: every JSON/YAML type, extreme numbers, odd text, nesting
# ----------------------------------------

NUMBERS = st.one_of(
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e300, -1e300, 1e-300, 2**63, -(2**63), 1e18, -1e18]),
)
TEXT = st.one_of(
    st.text(max_size=30),
    st.sampled_from(["", "\x00", "../../x", "/", "a" * 300, "é", "\ud7ff", "nan"]),
)
LEAF = st.one_of(st.none(), st.booleans(), NUMBERS, TEXT)
VALUE = st.recursive(
    LEAF,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)


def nested(depth: int):
    v: object = 1
    for _ in range(depth):
        v = {"a": v}
    return v


def mutate(doc: dict, path: list[str], value) -> dict:
    """``doc`` with the key at ``path`` (created where missing) set to ``value``; a non-mapping on
    the way is replaced by a mapping, so every path is reachable."""
    doc = json.loads(json.dumps(doc))
    cur = doc
    for k in path[:-1]:
        if not isinstance(cur.get(k), dict):
            cur[k] = {}
        cur = cur[k]
    cur[path[-1]] = value
    return doc


def key_paths(doc: dict, prefix=()) -> list[list[str]]:
    out = []
    for k, v in doc.items():
        out.append([*prefix, k])
        if isinstance(v, dict):
            out += key_paths(v, (*prefix, k))
    return out


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    log = write_log(d / "log.csv")
    (d / "plain.txt").write_text("x\n")
    return {
        "dir": d,
        "log": log,
        "meta": json.loads((d / "log.json").read_text()),
        "mission": yaml.safe_load(Path(SPIRAL).read_text()),
        "mat": mat_arrays(300),
        "plain": d / "plain.txt",
    }


SIDECAR_KEYS = [
    "rss_source",
    "rss_source.kind",
    "rss_source.model",
    "rss_source.seed",
    "rss_source.model_params",
    "trajectory",
    "trajectory.generator",
    "trajectory.params",
    "trajectory.altitude_m",
    "trajectory.adaptive",
    "live_estimate",
    "live_estimate.method",
    "truth",
    "truth.lat_deg",
    "truth.height_m",
    "origin",
    "origin.lat_deg",
    "origin.alt_m",
    "status",
    "rover_area",
    "format",
    "mission",
    "rows",
    "estimates",
    "budget",
]


@FUZZ
@given(data=st.data(), value=st.one_of(VALUE, st.integers(30, 300).map(nested)))
def test_generated_sidecars(base, tmp_path_factory, data, value):
    """A real sidecar with one key (known or existing) set to any JSON value or a deep nesting."""
    paths = [p.split(".") for p in SIDECAR_KEYS] + key_paths(base["meta"])
    path = data.draw(st.sampled_from(paths))
    d = tmp_path_factory.mktemp("sc")
    csv = d / "f.csv"
    csv.write_bytes(base["log"].read_bytes())
    (d / "f.json").write_text(json.dumps(mutate(base["meta"], path, value), allow_nan=True))
    for argv in (
        ["localize", csv, "--method", "centroid"],
        ["localize", csv, "--method", "centroid", "--json"],
    ):
        main = localize_main
        rc, _, err = call(main, argv[1:])
        assert_promise(rc, err, (path, value))


MISSION_KEYS = [
    "name",
    "altitude_m",
    "cruise_speed_mps",
    "time_budget_s",
    "fence_margin_m",
    "altitude_limits_m",
    "home",
    "return_behaviour",
    "trajectory",
    "trajectory.generator",
    "trajectory.params",
    "trajectory.params.spacing_m",
    "trajectory.waypoints",
    "source",
    "source.tx",
    "source.seed",
    "source.model",
    "source.noise_db",
    "source.model_params",
    "vehicle",
    "vehicle.connection",
    "vehicle.speedup",
    "vehicle.kinematics",
    "vehicle.kinematics.accel_mps2",
    "field",
    "field.preset",
    "field.origin",
    "field.flight_area",
    "adaptive",
    "adaptive.enabled",
]


@FUZZ
@given(data=st.data(), value=VALUE)
def test_generated_missions(base, tmp_path_factory, data, value):
    """The shipped spiral with one key set to any value, through ``rfsl export`` (parse, checks,
    write) and ``fly-mission`` (refused at the latest by its --out under a file: nothing starts)."""
    path = data.draw(
        st.sampled_from([p.split(".") for p in MISSION_KEYS] + key_paths(base["mission"]))
    )
    d = tmp_path_factory.mktemp("m")
    m = d / "m.yaml"
    m.write_text(yaml.safe_dump(mutate(base["mission"], path, value), allow_unicode=True))
    rc, _, err = call(rfsl_main, ["export", m, "--out", d / "m.plan"])
    assert_promise(rc, err, (path, value))
    rc, _, err = call(fly_main, [m, "--out", base["plain"] / "f"])
    assert_promise(rc, err, (path, value))
    assert rc == 2


@FUZZ
@given(
    text=st.one_of(
        st.binary(max_size=2000),
        st.text(max_size=400).map(lambda s: s.encode("utf-8", "surrogatepass")),
        st.sampled_from(
            [
                b"",
                b"\xef\xbb\xbf",
                b"a: &x [1]\nb: *x\n",
                b"a: 1\na: 2\n",
                b"[" * 3000,
                b"!!python/object:os.system x\n",
                "name: café\n".encode("latin-1"),
            ]
        ),
        st.integers(1, 5).map(lambda k: (b"altitude_m: 30\n" * k) + b"\xff"),
    )
)
def test_generated_mission_encodings(tmp_path_factory, text):
    """Any bytes as a mission file: binary, Latin-1, BOM, aliases, duplicates, tags, deep
    nesting."""
    d = tmp_path_factory.mktemp("e")
    m = d / "m.yaml"
    m.write_bytes(text)
    rc, _, err = call(rfsl_main, ["export", m, "--out", d / "m.plan"])
    assert_promise(rc, err, text[:80])


MAT_VARS = ["timestamp_power", "mX", "mY", "mZ", "mRoll", "mPitch", "mYaw", "mpower", "mquality"]
EXTREME = st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e300, -1e18, 1e18, 0.0, 400.0, -400.0])


@FUZZ
@given(
    var=st.sampled_from(MAT_VARS),
    kind=st.sampled_from(["values", "length", "text", "drop", "int", "matrix"]),
    idx=st.lists(st.integers(0, 299), min_size=1, max_size=300),
    v=EXTREME,
)
def test_generated_mat_files(base, tmp_path_factory, var, kind, idx, v):
    """A real-looking AFAR MAT file with one variable damaged: extreme values at some samples, the
    wrong length, text, missing, integers or a matrix; through ``rfsl import``."""
    m = dict(base["mat"])
    a = m[var].copy()
    if kind == "values":
        a[idx] = v
        m[var] = a
    elif kind == "length":
        m[var] = a[: len(idx)]
    elif kind == "text":
        m[var] = np.array(["x"] * len(a))
    elif kind == "drop":
        del m[var]
    elif kind == "int":
        m[var] = a.astype(np.int64)
    else:
        m[var] = np.tile(a, (2, 1))
    d = tmp_path_factory.mktemp("mat")
    sio.savemat(d / "f.mat", m)
    rc, out, err = call(rfsl_main, ["import", "afar-mat", d / "f.mat", "--out", d / "out"])
    assert_promise(rc, err, (var, kind, v))
    if rc == 0:  # what was written reads back (no silent wrong answer left for localize)
        rc2, _, err2 = call(localize_main, [d / "out" / "f.csv", "--method", "centroid"])
        assert_promise(rc2, err2, (var, kind, v, "localize"))


OPTION_VALUE = st.one_of(
    NUMBERS.map(repr),
    TEXT,
    st.sampled_from(
        ["1e9", "-0", "0x10", "1,2", "91,0", "nan,nan", "/dev/zero", "/proc/x", "", " ", "--"]
    ),
)
# (program, option, the rest of the command line: its last output path lies under a file)
OPTIONS = (
    [
        ("fly-mission", o, "{mission} --out {plain}/f")
        for o in (
            "--speedup",
            "--rate",
            "--link-timeout",
            "--land-timeout",
            "--connect",
            "--rss-source",
        )
    ]
    + [
        ("rfsl", o, "dataset {mission} --n 5 --out {plain}/ds")
        for o in ("--n", "--chunk", "--workers", "--altitude", "--noise", "--seed")
    ]
    + [("rfsl", o, "preview {mission} --out {plain}/p.png") for o in ("--size", "--grid", "--seed")]
    + [
        ("rfsl", o, "gap {log} --report {plain}/r")
        for o in (
            "--max-rungs",
            "--family-repeats",
            "--rate-hz",
            "--truth",
            "--truth-height",
            "--workers",
        )
    ]
    + [("rfsl", o, "simulate {mission} --out {plain}/s") for o in ("--source", "--seed", "--model")]
    + [
        ("localize", o, "{log} --method centroid --plot {plain}/x.png")
        for o in ("--at", "--tx-height", "--truth", "--origin", "--physics-preset")
    ]
)


@FUZZ
@given(case=st.sampled_from(OPTIONS), value=OPTION_VALUE)
def test_generated_options(base, case, value):
    """Any value for the options that size the work or name a place: refused in one line (a valid
    value is refused at the output path under a file), never a traceback or a start."""
    prog, opt, rest = case
    fill = {"mission": SPIRAL, "plain": base["plain"], "log": base["log"]}
    argv = [a.format(**fill) for a in rest.split()]
    argv = [*argv, f"{opt}={value}"]
    main = {"fly-mission": fly_main, "localize": localize_main, "rfsl": rfsl_main}[prog]
    rc, _, err = call(main, argv)
    assert_promise(rc, err, argv)
    assert rc == 2, (argv, err)


def test_the_promise_checker_catches_a_traceback():
    """The checker itself fails on what it must catch (a test that cannot fail proves nothing)."""
    with pytest.raises(AssertionError):
        assert_promise(1, "Traceback (most recent call last):\n", "x")
    with pytest.raises(AssertionError):
        assert_promise(2, "error: a\nerror: b\n", "x")
    assert math.isfinite(CALL_LIMIT_S)
