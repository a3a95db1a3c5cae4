"""Bad command-line arguments for every command: exit 2 and one stderr line naming the argument or
file, never a traceback, never a silent wrong answer; odd but valid input (negative coordinates)
accepted.

Each case calls the console script's ``main(argv)`` in-process.  ``fly-mission`` cases are only
those refused before anything connects (argument parsing and its first checks).  ``{log}``,
``{mission}``, ``{tmp}`` and friends in an argv are filled from the fixtures below.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import warnings

import numpy as np
import pytest
import scipy.io as sio
from _bad_input import SPIRAL, assert_accepted, assert_refused, run_cli, write_log
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from matplotlib.backend_bases import FigureCanvasBase

import mission.localize.api as api
from mission.cli.fly import main as fly_main
from mission.cli.localize import main as localize_main
from mission.cli.main import main as rfsl_main

HYPO = settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Paths the cases refer to: a good log, a one-row log, missions, MAT files, a plain file, a
    folder."""
    d = tmp_path_factory.mktemp("cli")
    log = write_log(d / "log.csv")
    short = write_log(d / "short.csv", n=60)
    one = d / "one.csv"
    one.write_text("\n".join(log.read_text().splitlines()[:2]) + "\n")
    (d / "one.json").write_text((d / "log.json").read_text())
    notruth = write_log(d / "notruth.csv", truth=False)
    (d / "far.yaml").write_text("source:\n  tx: [5000, 5000]\n")
    (d / "neg.yaml").write_text("source:\n  tx: [100, 150, -2]\n")
    (d / "bad.yaml").write_text("altitude_m: [oops\n")
    (d / "typo.yaml").write_text("altitude: 30\n")
    (d / "plain.txt").write_text("hello\n")
    (d / "empty").mkdir()
    (d / "exists.plan").write_text("{}")
    mats = d / "mats"
    mats.mkdir()
    n = 300
    t = 1.7e9 + np.arange(n) * 0.1
    lat = 35.728 + np.linspace(0, 1e-3, n)
    lon = np.full(n, -78.698)
    good = {
        "timestamp_power": t,
        "mX": lon,
        "mY": lat,
        "mZ": np.full(n, 30.0),
        "mRoll": np.zeros(n),
        "mPitch": np.zeros(n),
        "mYaw": np.zeros(n),
        "mpower": np.full(n, -50.0),
    }
    sio.savemat(mats / "a.mat", good)
    sio.savemat(mats / "b.mat", {**good, "timestamp_power": np.repeat(t[::2], 2)})
    bad = d / "badmats"
    bad.mkdir()
    sio.savemat(bad / "rad.mat", {**good, "mX": np.radians(lon), "mY": np.radians(lat)})
    sio.savemat(bad / "novar.mat", {k: v for k, v in good.items() if k != "mpower"})
    sio.savemat(bad / "ragged.mat", {**good, "mpower": np.zeros(n - 5)})
    sio.savemat(bad / "text.mat", {**good, "mpower": np.array(["a"] * n)})
    return {
        "dir": d,
        "log": log,
        "short": short,
        "one": one,
        "notruth": notruth,
        "mission": SPIRAL,
        "far": d / "far.yaml",
        "neg": d / "neg.yaml",
        "bad": d / "bad.yaml",
        "typo": d / "typo.yaml",
        "plain": d / "plain.txt",
        "empty": d / "empty",
        "exists": d / "exists.plan",
        "mats": mats,
        "badmats": bad,
    }


def _argv(template: str, files: dict, tmp) -> list[str]:
    """Split a case's argv template and fill ``{name}`` from ``files`` (``{tmp}``: the test's own
    folder)."""
    return [
        re.sub(r"\{(\w+)\}", lambda m: str(tmp if m.group(1) == "tmp" else files[m.group(1)]), a)
        for a in template.split()
    ]


MAINS = {"rfsl": rfsl_main, "localize": localize_main, "fly-mission": fly_main}

# (command line, substrings of the one error line)
REFUSED = [
    # rfsl rss
    ("rfsl rss --tx 0,0,1.5 --rx 0,0,1.5", ["--rx", "apart"]),
    ("rfsl rss --tx 0,0,1.5 --rx 0.01,0,1.5", ["--rx", "apart"]),
    ("rfsl rss --tx 1e300,0,1 --rx 0,0,30", ["--tx", "1e+06"]),
    ("rfsl rss --tx 0,0,1 --rx 0,-1e9,30", ["--rx"]),
    ("rfsl rss --tx 0,0,-1 --rx 5,5,30", ["--tx", "below ground"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,-3", ["--rx", "below ground"]),
    ("rfsl rss --tx 1,2 --rx 5,5,30", ["--tx", "three"]),
    ("rfsl rss --tx a,b,c --rx 5,5,30", ["--tx", "not a number"]),
    ("rfsl rss --tx nan,0,1 --rx 5,5,30", ["--tx", "non-finite"]),
    ("rfsl rss --tx 0,0,1 --rx inf,5,30", ["--rx", "non-finite"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --attitude 1,2", ["--attitude"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --attitude 0,0,1000", ["--attitude", "radians"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --attitude 400,0,0", ["--attitude"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --fc-hz 0", ["--fc-hz"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --fc-hz 1e30", ["--fc-hz"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --fc-hz nan", ["--fc-hz"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --eps-r -1", ["--eps-r"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --eps-r 0.5", ["--eps-r"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --pt-dbm 1e9", ["--pt-dbm"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --pt-dbm nan", ["--pt-dbm"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --beta -1", ["--beta"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --sigma -1", ["--sigma"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --pt-dbm abc", ["--pt-dbm", "invalid float"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --model nope", ["--model", "unknown model"]),
    ("rfsl rss --rx 5,5,30", ["--tx", "required"]),
    ("rfsl rss --tx --rx 5,5,30", ["--tx", "expected one argument"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --antenna nope", ["nope", "antenna"]),
    ("rfsl rss --tx 0,0,1 --rx 5,5,30 --antenna {empty}", ["empty", "antenna"]),
    # rfsl simulate
    ("rfsl simulate {mission} --source 5000,5000 --out {tmp}", ["--source", "outside"]),
    ("rfsl simulate {mission} --source 100,150,-1 --out {tmp}", ["--source", "below ground"]),
    ("rfsl simulate {mission} --source 1,2,3,4 --out {tmp}", ["--source"]),
    ("rfsl simulate {mission} --source abc --out {tmp}", ["--source"]),
    ("rfsl simulate {mission} --source nan,1 --out {tmp}", ["--source", "finite"]),
    ("rfsl simulate {mission} --seed -1 --out {tmp}", ["--seed"]),
    ("rfsl simulate {mission} --out {plain}", ["--out", "plain.txt", "not a folder"]),
    ("rfsl simulate {mission} --model nope", ["--model", "unknown model"]),
    ("rfsl simulate {tmp}/nope.yaml --out {tmp}", ["nope.yaml", "not found"]),
    ("rfsl simulate {bad} --out {tmp}", ["bad.yaml", "YAML"]),
    ("rfsl simulate {typo} --out {tmp}", ["typo.yaml", "altitude"]),
    ("rfsl simulate {far} --out {tmp}", ["far.yaml", "source.tx"]),
    ("rfsl simulate --out {tmp}", ["mission", "required"]),
    # rfsl preview
    ("rfsl preview {mission} --out {tmp}/p.foo", ["p.foo", "--out", "image format"]),
    ("rfsl preview {mission} --out {tmp}/p", ["--out", "no suffix"]),
    ("rfsl preview {mission} --out {empty}", ["empty", "--out", "directory"]),
    ("rfsl preview {mission} --out {plain}/p.png", ["--out", "not a folder"]),
    ("rfsl preview {mission} --size 10x10", ["--size"]),
    ("rfsl preview {mission} --size abc", ["--size"]),
    ("rfsl preview {mission} --grid 1", ["--grid"]),
    ("rfsl preview {mission} --grid 100000", ["--grid"]),
    ("rfsl preview {mission} --seed -1", ["--seed"]),
    ("rfsl preview {tmp}/nope.yaml --out {tmp}/p.png", ["nope.yaml"]),
    ("rfsl preview {empty} --out {tmp}/p.png", ["empty"]),
    # rfsl export
    ("rfsl export {mission} --out {empty}", ["empty", "--out", "directory"]),
    ("rfsl export {mission} --out {tmp}/x.gpx", ["x.gpx", "--out", "suffix"]),
    ("rfsl export {mission} --out {tmp}/x.kml --format plan", ["x.kml", "kml", "plan"]),
    ("rfsl export {mission} --out {plain}/x.plan", ["--out", "not a folder"]),
    ("rfsl export {mission} --out {exists}", ["exists.plan", "--overwrite"]),
    ("rfsl export {mission} --format nope", ["--format", "invalid choice"]),
    ("rfsl export {far} --out {tmp}/f.plan", ["far.yaml", "source.tx", "outside"]),
    ("rfsl export {neg} --out {tmp}/f.plan", ["neg.yaml", "source.tx", "below ground"]),
    ("rfsl export {tmp}/nope.yaml --out {tmp}/f.plan", ["nope.yaml"]),
    # rfsl replay
    ("rfsl replay {empty}", ["empty", "directory"]),
    ("rfsl replay {tmp}/nope.csv --out {tmp}/r.png", ["nope.csv", "no such"]),
    ("rfsl replay {log} --out {tmp}/r.foo", ["r.foo", "--out", "image format"]),
    ("rfsl replay {log} --out {empty}", ["--out", "directory"]),
    ("rfsl replay {log} --out {plain}/r.png", ["--out", "not a folder"]),
    ("rfsl replay {one} --out {tmp}/r.png", ["one.csv", "only 1 data row"]),
    ("rfsl replay {plain} --out {tmp}/r.png", ["plain.txt", "missing required column"]),
    ("rfsl replay {mats}/a.mat --out {tmp}/r.png", ["a.mat", "text"]),
    # rfsl import
    ("rfsl import afar-mat {empty} --out {tmp}", ["empty", "no .mat"]),
    ("rfsl import afar-mat {plain} --out {tmp}", ["plain.txt", "MATLAB"]),
    ("rfsl import afar-mat {tmp}/nope.mat --out {tmp}", ["nope.mat", "no such"]),
    ("rfsl import afar-mat {mats}/a.mat --out {tmp} --truth 95,0", ["--truth"]),
    ("rfsl import afar-mat {mats}/a.mat --out {tmp} --truth abc", ["--truth", "LAT,LON"]),
    (
        "rfsl import afar-mat {mats}/a.mat --out {tmp} --truth-height -1",
        ["--truth-height", "below ground"],
    ),
    ("rfsl import afar-mat {mats}/a.mat --out {plain}", ["--out", "plain.txt", "not a folder"]),
    ("rfsl import afar-mat {badmats}/rad.mat --out {tmp}", ["rad.mat", "'mY'", "radians"]),
    ("rfsl import afar-mat {badmats}/novar.mat --out {tmp}", ["novar.mat", "mpower"]),
    ("rfsl import afar-mat {badmats}/ragged.mat --out {tmp}", ["ragged.mat", "'mpower'", "rows"]),
    ("rfsl import afar-mat {badmats}/text.mat --out {tmp}", ["text.mat", "'mpower'"]),
    ("rfsl import gpx {mats}/a.mat --out {tmp}", ["kind", "invalid choice"]),
    ("rfsl import afar-mat {mats}/a.mat", ["--out", "required"]),
    # rfsl dataset
    ("rfsl dataset {mission} --n 0 --out {tmp}/ds", ["field 'n'", "must be >= 1, got 0"]),
    ("rfsl dataset {mission} --n 5 --out {plain}", ["--out", "not a folder"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --noise -1,2", ["--noise", "negative"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --tx-height -3,2", ["--tx-height", "negative"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --altitude 50,20", ["--altitude", "LO <= HI"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --altitude abc", ["--altitude"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --workers 0", ["--workers"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --trajectories zig", ["--trajectories", "zig"]),
    ("rfsl dataset {mission} --n 5 --out {tmp}/ds --physics nope", ["preset", "nope"]),
    ("rfsl dataset {mission} --n abc --out {tmp}/ds", ["--n", "invalid int"]),
    ("rfsl dataset {mission} --out {tmp}/ds", ["--n", "required"]),
    # rfsl evaluate
    ("rfsl evaluate", ["nothing to evaluate"]),
    ("rfsl evaluate --models {tmp}/nope.onnx --real {log}", ["nope.onnx", "no such model"]),
    ("rfsl evaluate --real {empty}", ["empty", "directory"]),
    ("rfsl evaluate --real {one}", ["one.csv", "only 1 data row"]),
    ("rfsl evaluate --real {notruth} --methods centroid", ["notruth.csv", "truth"]),
    ("rfsl evaluate --methods foo --real {log}", ["--methods", "foo"]),
    ("rfsl evaluate --afar {plain}", ["plain.txt", ".mat"]),
    ("rfsl evaluate --sim-test {empty}", ["empty", "manifest"]),
    ("rfsl evaluate --real {log} --out {empty}", ["--out", "directory"]),
    ("rfsl evaluate --real {log} --out {plain}/r.json", ["--out", "not a folder"]),
    # rfsl gap
    ("rfsl gap", ["logs", "at least one"]),
    ("rfsl gap {empty}", ["empty", "directory"]),
    ("rfsl gap {one}", ["one.csv", "only 1 data row"]),
    ("rfsl gap {short} --no-localize", ["short.csv", "samples"]),
    ("rfsl gap {notruth}", ["notruth.csv", "truth"]),
    ("rfsl gap {log} --truth 95,0", ["truth"]),
    ("rfsl gap {log} --truth abc", ["truth", "LAT,LON"]),
    ("rfsl gap {log} --truth 1,2 --truth 3,4 --truth 5,6", ["truth", "once per log"]),
    ("rfsl gap {log} --base nope", ["base", "nope"]),
    ("rfsl gap {log} --candidates nope --no-localize", ["candidates", "nope"]),
    ("rfsl gap --selftest --seeds abc", ["--seeds"]),
    ("rfsl gap --selftest --withheld nope", ["withheld", "nope"]),
    ("rfsl gap {log} --loss nope", ["--loss", "invalid choice"]),
    # localize
    ("localize {empty}", ["empty", "directory"]),
    ("localize {tmp}/nope.csv", ["nope.csv", "no such"]),
    ("localize {one}", ["one.csv", "only 1 data row"]),
    ("localize {log} --method grid --physics e2r --tx-height 5000", ["--tx-height"]),
    ("localize {log} --plot {tmp}/x.foo", ["x.foo", "--plot", "image format"]),
    ("localize {log} --plot {empty}", ["--plot", "directory"]),
    ("localize {log} --truth abc", ["--truth", "LAT,LON"]),
    ("localize {log} --truth 95,0", ["--truth"]),
    ("localize {log} --origin abc", ["--origin"]),
    ("localize {log} --origin 95,0", ["--origin"]),
    ("localize {log} --origin 35.7,-78.7,1e9", ["--origin", "altitude"]),
    ("localize {log} --origin 0,0", ["'lat_deg'", "km from the origin"]),
    ("localize {log} --model {tmp}/m.onnx --method grid", ["--model", "--method onnx"]),
    ("localize {log} --model {tmp}/nope.onnx", ["nope.onnx", "no such model"]),
    ("localize {log} --model {plain}", ["plain.txt", "ONNX"]),
    ("localize {log} --method nope", ["--method", "invalid choice"]),
    ("localize {log} --tx-height -1", ["--tx-height"]),
    ("localize {log} --tx-height nan", ["--tx-height"]),
    ("localize {log} --physics nope", ["--physics", "nope"]),
    ("localize {log} --physics-preset nope", ["--physics-preset", "nope"]),
    ("localize {log} --physics-preset afar:nope", ["--physics-preset", "fold"]),
    ("localize", ["LOG.csv", "required"]),
    # fly-mission: refused before anything starts or connects
    ("fly-mission", ["mission", "required"]),
    ("fly-mission {mission} --speedup abc", ["--speedup", "invalid float"]),
    ("fly-mission {mission} --speedup -1", ["--speedup", "positive"]),
    ("fly-mission {mission} --speedup 0", ["--speedup", "positive"]),
    ("fly-mission {mission} --rate 10", ["--rate", "30"]),
    ("fly-mission {mission} --rate abc", ["--rate", "invalid float"]),
    ("fly-mission {mission} --link-timeout abc", ["--link-timeout", "invalid float"]),
    ("fly-mission {mission} --land-timeout x", ["--land-timeout", "invalid float"]),
    ("fly-mission {mission} --bogus", ["unrecognized arguments", "--bogus"]),
    # rfsl itself
    ("rfsl nope", ["invalid choice", "nope"]),
    ("rfsl", ["COMMAND", "required"]),
    ("rfsl sitl --speedup -1", ["--speedup"]),
    ("rfsl sitl --port abc", ["--port", "invalid int"]),
    ("rfsl train {empty} --out {tmp}/m.onnx", ["empty"]),
]


@pytest.mark.parametrize("cmd, names", REFUSED, ids=[c for c, _ in REFUSED])
def test_bad_argument_is_one_line_exit_2(files, tmp_path, capsys, cmd, names):
    prog, _, rest = cmd.partition(" ")
    if prog == "rfsl" and rest.startswith("train"):
        pytest.importorskip("torch")
    rc, _, err = run_cli(MAINS[prog], _argv(rest, files, tmp_path), capsys)
    assert_refused(rc, err, *names)


# (command line, what stdout or stderr must show)
ACCEPTED = [
    ("rfsl rss --tx -100,200,1.5 --rx 0,0,30", "dBm"),
    ("rfsl rss --tx -100,-200,1.5 --rx -50,-20,30 --json", "rss_dbm"),
    ("rfsl rss --tx=-5,-5,1 --rx 10,10,30", "dBm"),
    ("rfsl rss --tx -.5,1,1 --rx 10,10,30 --attitude -2,-3,-90", "dBm"),
    ("rfsl rss --tx 0,0,0 --rx 0,0,0.1", "dBm"),
    ("rfsl export {mission} --out {tmp}/m.waypoints", "wpl"),
    ("rfsl export {far} --out {tmp}/f.plan --force", "FAILS CHECKS"),
    ("rfsl import afar-mat {mats} --out {tmp}", "a.csv"),
    ("rfsl import afar-mat {mats}/b.mat --out {tmp}", "duplicate timestamps"),
    ("localize {log} --method centroid --tx-height 0", "centroid"),
    ("rfsl gap --selftest --withheld none --seeds 1 --help", "usage"),
]


@pytest.mark.parametrize("cmd, shown", ACCEPTED, ids=[c for c, _ in ACCEPTED])
def test_valid_odd_argument_is_accepted(files, tmp_path, capsys, cmd, shown):
    prog, _, rest = cmd.partition(" ")
    rc, out, err = run_cli(MAINS[prog], _argv(rest, files, tmp_path), capsys)
    assert_accepted(rc, err)
    assert shown in out + err


def test_export_refuses_to_overwrite_unless_asked(files, tmp_path, capsys):
    out = tmp_path / "m.plan"
    assert run_cli(rfsl_main, ["export", SPIRAL, "--out", out], capsys)[0] == 0
    first = out.read_text()
    out.write_text("mine")
    rc, _, err = run_cli(rfsl_main, ["export", SPIRAL, "--out", out], capsys)
    assert_refused(rc, err, "--overwrite")
    assert out.read_text() == "mine"
    assert run_cli(rfsl_main, ["export", SPIRAL, "--out", out, "--overwrite"], capsys)[0] == 0
    assert out.read_text() == first


def test_preview_of_a_far_transmitter_is_not_flyable(files, tmp_path, capsys):
    rc, out, err = run_cli(
        rfsl_main, ["preview", files["far"], "--out", tmp_path / "p.png"], capsys
    )
    assert_accepted(rc, err)
    assert "no: transmitter at (5000.0, 5000.0) m" in " ".join(out.split())


def test_import_of_a_folder_imports_every_mat(files, tmp_path, capsys):
    rc, out, err = run_cli(
        rfsl_main, ["import", "afar-mat", files["mats"], "--out", tmp_path], capsys
    )
    assert_accepted(rc, err)
    assert sorted(p.name for p in tmp_path.glob("*.csv")) == ["a.csv", "b.csv"]


def test_image_suffix_is_checked_before_the_work(files, tmp_path, capsys, monkeypatch):
    """--plot x.foo must fail before localizing, not after (a traceback after minutes of work
    before)."""

    def boom(*a, **k):
        raise AssertionError("localized before checking --plot")

    monkeypatch.setattr(api, "localize_log", boom)
    rc, _, err = run_cli(localize_main, [files["log"], "--plot", tmp_path / "x.foo"], capsys)
    assert_refused(rc, err, "--plot")


# --- generated with hypothesis
# -----------------------------------------------------------------------------

coord = st.one_of(
    st.floats(-2e3, 2e3),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e6, -1e6, 1e300, 1e-300]),
)


@HYPO
@given(tx=st.tuples(coord, coord, coord), rx=st.tuples(coord, coord, coord))
def test_generated_rss_geometry_never_gives_nan_or_warnings(tx, rx):
    """Any --tx/--rx: a finite dBm value with exit 0, or exit 2 with one line naming --tx or
    --rx."""
    argv = [
        "rss",
        "--model",
        "e2r",
        "--tx",
        ",".join(map(repr, tx)),
        "--rx",
        ",".join(map(repr, rx)),
        "--json",
    ]
    out, err = io.StringIO(), io.StringIO()
    with (
        warnings.catch_warnings(),
        contextlib.redirect_stdout(out),
        contextlib.redirect_stderr(err),
    ):
        warnings.simplefilter("error")  # a numpy RuntimeWarning fails the case
        rc = rfsl_main(argv)
    if rc == 0:
        assert math.isfinite(json.loads(out.getvalue())["rss_dbm"])
        assert err.getvalue() == ""
    else:
        assert_refused(rc, err.getvalue())
        assert "--tx" in err.getvalue() or "--rx" in err.getvalue()


@HYPO
@given(xyz=st.tuples(st.floats(-1e4, -0.01), st.floats(-1e4, 1e4), st.floats(0.5, 100)))
def test_generated_negative_coordinates_are_accepted(capsys, xyz):
    """Negative coordinates after an option (``--tx -100,200,1.5``) are values, not options."""
    text = ",".join(f"{v:.3f}" for v in xyz)
    rc, out, err = run_cli(
        rfsl_main, ["rss", "--tx", text, "--rx", "1,1,30", "--model", "free-space"], capsys
    )
    if math.dist(xyz, (1, 1, 30)) >= 0.1:
        assert_accepted(rc, err)
        assert out.strip().endswith("dBm")


@HYPO
@given(
    suffix=st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789", min_size=1, max_size=5),
    cmd=st.sampled_from(["localize", "replay", "preview"]),
)
def test_generated_image_suffixes(files, capsys, suffix, cmd):
    """Any --plot/--out suffix: a matplotlib format is taken, anything else refused naming the
    option."""
    known = suffix in FigureCanvasBase.get_supported_filetypes()
    out = files["dir"] / "gen" / f"x.{suffix}"
    argv = {
        "localize": (localize_main, [files["one"], "--plot", out]),
        "replay": (rfsl_main, ["replay", files["one"], "--out", out]),
        "preview": (rfsl_main, ["preview", files["plain"], "--out", out]),
    }[cmd]
    rc, _, err = run_cli(*argv, capsys)
    if known:  # the suffix passes; the (bad) input behind it is what is refused
        assert_refused(rc, err)
        assert "image format" not in err
    else:
        assert_refused(rc, err, "image format", "--plot" if cmd == "localize" else "--out")
