"""Issue 37's sweep of malformed inputs, one case each: exit 2 with exactly one stderr line naming
the file or field, never a traceback, nothing started, nothing written outside the folder named.

Every case calls a console script's ``main(argv)`` in-process (``fly-mission`` cases are refused
before any vehicle starts: a case that started one would hang the test, not pass it).  ``{name}`` in
an argv is filled from the ``files`` fixture, ``{tmp}`` with the test's own folder.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import scipy.io as sio
from _bad_input import SPIRAL, assert_accepted, assert_refused, mat_arrays, run_cli, write_log

from mission.cli.fly import main as fly_main
from mission.cli.localize import main as localize_main
from mission.cli.main import main as rfsl_main
from mission.localize.onnx_model import OnnxLocalizer
from mission.shipped import (
    file_sha256,
    missions_dir,
    models_dir,
    resolve_shipped,
    shipped_digests,
    shipped_model,
)
from mission.spec import load_mission
from mission.workshop.dataset import FORMAT, DatasetConfig

MAINS = {"rfsl": rfsl_main, "localize": localize_main, "fly-mission": fly_main}


def _bomb() -> str:
    """The YAML "billion laughs": nine levels of nine aliases (9**9 strings if expanded)."""
    text = 'a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n'
    for prev, cur in zip("abcdefgh", "bcdefghi", strict=True):
        text += f"{cur}: &{cur} [{', '.join([f'*{prev}'] * 9)}]\n"
    return "trajectory:\n  params:\n" + "".join("    " + ln + "\n" for ln in text.splitlines())


MISSIONS = {
    "bomb": _bomb(),
    "empty": "",
    "comments": "# nothing but a comment\n",
    "dup": "altitude_m: 30\naltitude_m: 40\n",
    "seedneg": "source:\n  seed: -1\n",
    "alt308": "altitude_m: 1.0e+308\n",
    "wp300": "trajectory:\n  waypoints: [[1.0e+300, 0], [10, 10]]\n",
    "tx300": "source:\n  tx: [1.0e+300, 5]\n",
    "budget300": "time_budget_s: 1.0e+300\n",
    "speedup": "vehicle:\n  speedup: 1.0e+9\n",
    "escape": "name: ../../escaped_by_name\n",
    "slash": "name: a/b\n",
    "nul": 'name: "a\\0b"\n',
    "long": f"name: {'n' * 300}\n",
    "dots": "name: ..\n",
    "conn": "vehicle:\n  connection: garbage\n",
    "conn256": "vehicle:\n  connection: udpin://256.1.1.1:14540\n",
    "deep": "a: " + "[" * 5000 + "]" * 5000 + "\n",
    # a key that holds line breaks: still one error line
    "ctrl": 'trajectory:\n  "a\\x1db\\nc": 1\n',
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("r3")
    log = write_log(d / "log.csv")
    meta = json.loads((d / "log.json").read_text())
    for name, key, value in (
        ("rss_str", "rss_source", "x"),
        ("rss_list", "rss_source", [1]),
        ("traj_str", "trajectory", "spiral"),
        ("traj_list", "trajectory", [1, 2]),
        ("live_str", "live_estimate", "selfcal"),
        ("live_list", "live_estimate", [1]),
        ("gen_num", "trajectory", {"generator": 5}),
    ):
        shutil.copy(log, d / f"{name}.csv")
        (d / f"{name}.json").write_text(json.dumps({**meta, key: value}))
    shutil.copy(log, d / "nest.csv")
    (d / "nest.json").write_text('{"a":' * 100000 + "1" + "}" * 100000)
    lines = log.read_text().splitlines()
    head = lines[0].split(",")
    row = lines[40].split(",")
    row[head.index("rss_dbm")] = "300"
    (d / "rss300.csv").write_text("\n".join([*lines[:40], ",".join(row), *lines[41:]]) + "\n")
    shutil.copy(d / "log.json", d / "rss300.json")
    for name, text in MISSIONS.items():
        (d / f"{name}.yaml").write_text(text)
    (d / "nonutf.yaml").write_bytes(b"name: caf\xe9\n")
    (d / "binary.yaml").write_bytes(bytes(range(256)) * 8)
    # 30 MB, sparse: refused by its size before a byte is read
    with open(d / "big.yaml", "wb") as f:
        f.truncate(30_000_000)
    (d / "rand.json").write_bytes(np.random.default_rng(0).bytes(3000))
    (d / "plain.txt").write_text("x\n")
    (d / "family.json").write_text("{}")
    (d / "report").mkdir()
    (d / "report" / "gap.json").write_text("{}")
    os.mkfifo(d / "fifo")
    good = mat_arrays(300)
    sio.savemat(d / "tneg.mat", {**good, "timestamp_power": -1e18 + np.arange(300) * 0.1})
    for name, var, k, v in (
        ("p300", "mpower", 5, 1e300),
        ("y300", "mYaw", 7, 1e300),
        ("t300", "timestamp_power", 3, 1e300),
        ("dbm300", "mpower", 9, 300.0),
        ("roll", "mRoll", 11, 200.0),
    ):
        a = good[var].copy()
        a[k] = v
        sio.savemat(d / f"{name}.mat", {**good, var: a})
    ds = d / "ds"  # a dataset whose one chunk is damaged
    ds.mkdir()

    # the manifest matches the network evaluate runs
    net = OnnxLocalizer(shipped_model("rfsl_default.onnx"))
    (ds / "manifest.json").write_text(
        json.dumps(
            {
                "format": FORMAT,
                "config": DatasetConfig(SPIRAL, n=5).to_dict(),
                "n": 5,
                "feature_config": net.cfg.to_dict(),
                "field_origin": net.origin.to_dict(),
                "chunks": [{"file": "chunk_00000.npz", "n": 5, "first_index": 0, "sha256": "0"}],
            }
        )
    )
    (d / "ds_nocfg").mkdir()
    (d / "ds_nocfg" / "manifest.json").write_text(json.dumps({"format": FORMAT, "chunks": []}))
    (ds / "chunk_00000.npz").write_bytes(b"PK\x03\x04" + bytes(100))
    return {
        "dir": d,
        "log": log,
        "mission": SPIRAL,
        "net": shipped_model("rfsl_default.onnx"),
        **{k: d / f"{k}.yaml" for k in MISSIONS},
        "rand": d / "rand.json",
        "nonutf": d / "nonutf.yaml",
        "binary": d / "binary.yaml",
        "big": d / "big.yaml",
        "fifo": d / "fifo",
        "plain": d / "plain.txt",
        "family": d / "family.json",
        "report": d / "report",
        "ds": ds,
        "ds_nocfg": d / "ds_nocfg",
        **{
            k: d / f"{k}.csv"
            for k in (
                "rss_str",
                "rss_list",
                "traj_str",
                "traj_list",
                "live_str",
                "live_list",
                "gen_num",
                "nest",
                "rss300",
            )
        },
        **{k: d / f"{k}.mat" for k in ("tneg", "p300", "y300", "t300", "dbm300", "roll")},
    }


def _argv(template: str, files: dict, tmp) -> list[str]:
    out = []
    for a in template.split():
        a = re.sub(
            r"\{(\w+)\}", lambda m: str(tmp if m.group(1) == "tmp" else files[m.group(1)]), a
        )
        out.append("" if a == "''" else a)
    return out


# (command line, substrings of the one error line)
REFUSED = [
    # sidecars: every field the readers use has its type checked
    ("localize {rss_str}", ["rss_str.json", "'rss_source'", "object"]),
    ("localize {rss_list}", ["rss_list.json", "'rss_source'", "object"]),
    ("localize {traj_str}", ["traj_str.json", "'trajectory'"]),
    ("localize {traj_list}", ["traj_list.json", "'trajectory'"]),
    ("localize {live_str}", ["live_str.json", "'live_estimate'"]),
    ("localize {live_list}", ["live_list.json", "'live_estimate'"]),
    ("localize {gen_num}", ["gen_num.json", "'trajectory.generator'", "string"]),
    ("localize {nest}", ["nest.json", "nested too deeply"]),
    ("localize {rss300}", ["rss300.csv", "row 41", "'rss_dbm'", "plausible"]),
    ("rfsl replay {rss_list} --out {tmp}/r.png", ["'rss_source'"]),
    ("rfsl gap {traj_str} --no-localize", ["'trajectory'"]),
    # inputs that are not regular files
    ("localize /dev/zero", ["/dev/zero", "not a regular file"]),
    ("localize {fifo}", ["fifo", "not a regular file"]),
    ("rfsl simulate {fifo} --out {tmp}", ["fifo", "not a regular file"]),
    ("rfsl simulate /dev/zero --out {tmp}", ["/dev/zero", "not a regular file"]),
    # options
    ("localize {log} --plot /proc/rfsl/x.png", ["--plot", "cannot write"]),
    ("localize {log} --plot {plain}/x.png", ["--plot", "not a folder"]),
    ("localize {log} --physics-preset {rand}", ["--physics-preset", "UTF-8"]),
    ("rfsl dataset --suite unseen --family {rand} --n 5 --out {tmp}/ds", ["rand.json", "UTF-8"]),
    ("rfsl evaluate --sim-test {ds} --models {net}", ["chunk_00000.npz", "damaged"]),
    ("rfsl evaluate --sim-test {ds_nocfg}", ["manifest.json", "config"]),
    # mission files: YAML limits, names, ranges
    ("rfsl simulate {bomb} --out {tmp}", ["bomb.yaml", "alias"]),
    ("rfsl simulate {big} --out {tmp}", ["big.yaml", "30.0 MB", "at most 1 MB"]),
    ("rfsl simulate {empty} --out {tmp}", ["empty.yaml", "empty mission file"]),
    ("rfsl simulate {comments} --out {tmp}", ["comments.yaml", "empty mission file"]),
    ("rfsl simulate {dup} --out {tmp}", ["dup.yaml", "duplicated key 'altitude_m'", "line 2"]),
    ("rfsl simulate {deep} --out {tmp}", ["deep.yaml"]),
    ("rfsl simulate {ctrl} --out {tmp}", ["ctrl.yaml", "'trajectory.a\\x1db\\nc'", "unknown key"]),
    ("rfsl simulate {nonutf} --out {tmp}", ["nonutf.yaml", "UTF-8"]),
    ("rfsl simulate {binary} --out {tmp}", ["binary.yaml"]),
    ("rfsl simulate {seedneg} --out {tmp}", ["seedneg.yaml", "'source.seed'", ">= 0"]),
    ("rfsl simulate {alt308} --out {tmp}", ["alt308.yaml", "'altitude_m'", "<= 10000"]),
    ("rfsl simulate {wp300} --out {tmp}", ["wp300.yaml", "'trajectory.waypoints[0]'", "1e+06 m"]),
    ("rfsl simulate {tx300} --out {tmp}", ["tx300.yaml", "'source.tx'"]),
    ("rfsl simulate {budget300} --out {tmp}", ["budget300.yaml", "'time_budget_s'"]),
    ("rfsl simulate {speedup} --out {tmp}", ["speedup.yaml", "'vehicle.speedup'", "1000"]),
    ("rfsl simulate {escape} --out {tmp}", ["escape.yaml", "'name'", "'/'"]),
    ("rfsl simulate {slash} --out {tmp}", ["slash.yaml", "'name'"]),
    ("rfsl simulate {nul} --out {tmp}", ["nul.yaml", "'name'", "\\x00"]),
    ("rfsl simulate {long} --out {tmp}", ["long.yaml", "'name'", "300 characters"]),
    ("rfsl simulate {dots} --out {tmp}", ["dots.yaml", "'name'"]),
    ("rfsl export {escape} --out {tmp}/e.plan", ["escape.yaml", "'name'"]),
    # counts, sizes and rates bounded
    ("rfsl dataset {mission} --n 1000000000 --out {tmp}/ds", ["--n", "1,000,000"]),
    ("rfsl dataset {mission} --n 5 --chunk 0 --out {tmp}/ds", ["--chunk"]),
    ("rfsl preview {mission} --size 100000x100000 --out {tmp}/p.png", ["--size", "8000"]),
    ("rfsl sitl --port 99999", ["--port", "1-65535"]),
    ("rfsl sitl --port -1", ["--port", "1-65535"]),
    ("rfsl sitl --port 0", ["--port"]),
    ("rfsl sitl --home 91,0", ["--home"]),
    ("rfsl sitl --home 35,-78,1e9", ["--home", "altitude"]),
    ("rfsl sitl --url garbage", ["--url", "SCHEME:HOST:PORT"]),
    ("rfsl sitl --url udpin:256.1.1.1:14540", ["--url", "256.1.1.1"]),
    ("rfsl sitl --url udpin:0.0.0.0:99999", ["--url", "1-65535"]),
    ("rfsl sitl --duration -1", ["--duration"]),
    ("rfsl sitl --speedup nan", ["--speedup", "finite"]),
    ("rfsl sitl --speedup 1e9", ["--speedup", "1000"]),
    ("rfsl sitl --gust inf", ["--gust"]),
    ("rfsl sitl --seed -1", ["--seed"]),
    ("rfsl gap {log} --max-rungs -1", ["--max-rungs", ">= 0"]),
    ("rfsl gap {log} --family-repeats -2", ["--family-repeats"]),
    ("rfsl gap {log} --rate-hz nan", ["--rate-hz"]),
    ("rfsl gap {log} --rate-hz inf", ["--rate-hz"]),
    ("rfsl gap {log} --workers 100000", ["--workers", "1..256"]),
    ("rfsl dataset {mission} --n 5 --workers 100000 --out {tmp}/ds", ["--workers", "1..256"]),
    ("rfsl evaluate --real {log} --workers 0", ["--workers"]),
    ("fly-mission {mission} --speedup nan", ["--speedup", "finite"]),
    ("fly-mission {mission} --speedup inf", ["--speedup", "finite"]),
    ("fly-mission {mission} --speedup 1e9", ["--speedup", "1000"]),
    ("fly-mission {mission} --rate nan", ["--rate", "finite"]),
    ("fly-mission {mission} --rate 1e9", ["--rate", "1000"]),
    ("fly-mission {mission} --link-timeout nan", ["--link-timeout"]),
    ("fly-mission {mission} --land-timeout -5", ["--land-timeout"]),
    ("fly-mission {mission} --land-timeout 1e300", ["--land-timeout"]),
    ("fly-mission {mission} --link-timeout=--", ["--link-timeout", "one value"]),
    ("rfsl dataset {mission} --n=-- --out {tmp}/ds", ["--n", "one value"]),
    # --connect: a malformed address is bad input at once (an unreachable one is a dead link, exit
    # 3)
    (
        "fly-mission {mission} --connect udpin://256.1.1.1:14540",
        ["--connect", "256.1.1.1", "IP address"],
    ),
    ("fly-mission {mission} --connect tcpout://bad_host!:5760", ["--connect", "host name"]),
    ("fly-mission {mission} --connect udpin://0.0.0.0:0", ["--connect", "HOST:PORT"]),
    (
        "fly-mission {mission} --connect serial:///dev/rfsl-no-such-tty:57600",
        ["--connect", "no such serial device"],
    ),
    ("fly-mission {mission} --connect ''", ["--connect", "empty connection"]),
    ("fly-mission {mission} --connect garbage", ["--connect", "unknown connection"]),
    ("fly-mission {mission} --connect gopher://x:1", ["--connect", "unknown connection"]),
    ("fly-mission {conn}", ["conn.yaml", "'vehicle.connection'", "unknown connection"]),
    ("fly-mission {conn256}", ["conn256.yaml", "'vehicle.connection'", "256.1.1.1"]),
    # names and output paths, refused before the vehicle starts
    ("fly-mission {escape} --out {tmp}/f", ["escape.yaml", "'name'"]),
    ("fly-mission {slash} --out {tmp}/f", ["slash.yaml", "'name'"]),
    ("fly-mission {nul} --out {tmp}/f", ["nul.yaml", "'name'"]),
    ("fly-mission {long} --out {tmp}/f", ["long.yaml", "'name'"]),
    ("fly-mission {mission} --out /proc/rfsl-flights", ["--out", "cannot write"]),
    ("fly-mission {mission} --out {plain}/f", ["--out", "plain.txt"]),
    ("fly-mission {bomb}", ["bomb.yaml", "alias"]),
    ("fly-mission {empty}", ["empty.yaml", "empty mission file"]),
    ("fly-mission {fifo}", ["fifo", "not a regular file"]),
    # outputs that exist or cannot be written
    ("rfsl gap {log} --family {family}", ["family.json", "--family", "--overwrite"]),
    ("rfsl gap {log} --report {report}", ["report", "--report", "gap.json"]),
    ("rfsl gap {log} --report {plain}/r", ["--report", "not a folder"]),
    ("rfsl gap {log} --report {plain}", ["--report", "not a folder"]),
    ("rfsl gap --selftest --report {plain}/r", ["--report", "not a folder"]),
    ("rfsl export {mission} --out /proc/rfsl/x.plan", ["--out", "cannot write"]),
    ("rfsl simulate {mission} --out /proc/rfsl", ["--out", "cannot write"]),
    ("rfsl import afar-mat {p300} --out /proc/rfsl", ["--out", "cannot write"]),
    # MAT files
    ("rfsl import afar-mat {tneg} --out {tmp}", ["tneg.mat", "Unix seconds"]),
]


@pytest.mark.parametrize("cmd, names", REFUSED, ids=[c for c, _ in REFUSED])
def test_refused_in_one_line(files, tmp_path, capsys, cmd, names):
    prog, _, rest = cmd.partition(" ")
    rc, _, err = run_cli(MAINS[prog], _argv(rest, files, tmp_path), capsys)
    assert_refused(rc, err, *names)


# (MAT file, the note that names the dropped samples)
DROPPED = [
    ("p300", "sample 6"),
    ("y300", "sample 8"),
    ("t300", "sample 4"),
    ("dbm300", "sample 10"),
    ("roll", "sample 12"),
]


@pytest.mark.parametrize("mat, note", DROPPED, ids=[m for m, _ in DROPPED])
def test_impossible_mat_samples_are_dropped_with_a_note(files, tmp_path, capsys, mat, note):
    rc, out, err = run_cli(rfsl_main, ["import", "afar-mat", files[mat], "--out", tmp_path], capsys)
    assert_accepted(rc, err)
    assert "dropped 1 sample(s)" in out and note in out, out
    assert "299 samples" in out


def test_a_mission_name_never_leaves_the_output_folder(files, tmp_path, capsys):
    """The escape case writes nothing anywhere: not under --out, not two levels above it."""
    out = tmp_path / "a" / "b" / "flights"
    rc, _, err = run_cli(rfsl_main, ["simulate", files["escape"], "--out", out], capsys)
    assert_refused(rc, err, "'name'")
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []


def test_simulate_and_import_do_not_replace_a_sidecar(files, tmp_path, capsys):
    """A sidecar of the same name (its CSV gone) is kept, for simulate and for import without
    --overwrite."""
    side = tmp_path / "spiral_sim_e2r_seed0.json"
    side.write_text('{"mine": 1}')
    rc, _, err = run_cli(rfsl_main, ["simulate", SPIRAL, "--out", tmp_path], capsys)
    assert_refused(rc, err, "spiral_sim_e2r_seed0.json", "exists already")
    (tmp_path / "p300.json").write_text('{"mine": 2}')
    rc, _, err = run_cli(
        rfsl_main, ["import", "afar-mat", files["p300"], "--out", tmp_path], capsys
    )
    assert_refused(rc, err, "p300.json", "--overwrite")
    assert (
        side.read_text() == '{"mine": 1}' and (tmp_path / "p300.json").read_text() == '{"mine": 2}'
    )
    assert (
        not (tmp_path / "spiral_sim_e2r_seed0.csv").exists()
        and not (tmp_path / "p300.csv").exists()
    )


def test_shipped_missions_and_models_resolve_from_any_folder(tmp_path, monkeypatch):
    """After a plain pip install the README's names work outside the clone: ``spiral``,
    ``missions/spiral.yaml`` and ``rfsl_default.onnx`` fall back to the shipped copies; a file of
    that name in the folder wins."""
    monkeypatch.chdir(tmp_path)
    for name in ("spiral", "spiral.yaml", "missions/spiral.yaml"):
        assert load_mission(name).path == missions_dir() / "spiral.yaml"
    assert (
        resolve_shipped("rfsl_default.onnx", "models", ".onnx")
        == models_dir() / "rfsl_default.onnx"
    )
    assert (
        resolve_shipped("models/rfsl_default.onnx", "models", ".onnx")
        == models_dir() / "rfsl_default.onnx"
    )
    (tmp_path / "spiral.yaml").write_text("name: mine\n")
    assert load_mission("spiral.yaml").name == "mine"
    assert resolve_shipped("elsewhere/x.onnx", "models", ".onnx").as_posix() == "elsewhere/x.onnx"


@pytest.mark.parametrize("value", ["a\x1db", "a\nb", "a\u2028b"])
def test_an_option_value_with_a_line_break_stays_one_line(capsys, value):
    rc, _, err = run_cli(rfsl_main, ["simulate", SPIRAL, "--model", value], capsys)
    assert_refused(rc, err, "--model", repr(value)[2:-2])


def test_shipped_digests_match_the_shipped_networks():
    """models/sha256.json holds every shipped network's digest (``rfsl train --out models/X.onnx``
    updates it)."""
    nets = sorted(p.name for p in models_dir().glob("*.onnx"))
    assert sorted(shipped_digests()) == nets
    for name in nets:
        assert file_sha256(models_dir() / name) == shipped_digests()[name], (
            f"update models/sha256.json for {name}"
        )


@pytest.mark.parametrize("where", ["middle", "end"])
def test_a_shipped_network_with_flipped_bytes_is_refused(files, tmp_path, capsys, where):
    """Bytes flipped in the weights still load and answer (wrongly); under a shipped name it is
    refused."""
    data = bytearray(shipped_model("rfsl_default.onnx").read_bytes())
    at = len(data) // 2 if where == "middle" else len(data) - 200
    data[at : at + 16] = bytes(b ^ 0xFF for b in data[at : at + 16])
    (tmp_path / "rfsl_default.onnx").write_bytes(bytes(data))
    rc, _, err = run_cli(
        localize_main, [files["log"], "--model", tmp_path / "rfsl_default.onnx"], capsys
    )
    assert_refused(rc, err, "rfsl_default.onnx", "differs from the shipped")
    # a copy renamed: fine
    (tmp_path / "mine.onnx").write_bytes(shipped_model("rfsl_default.onnx").read_bytes())
    rc, _, err = run_cli(
        localize_main, [files["log"], "--model", tmp_path / "mine.onnx", "--json"], capsys
    )
    assert rc == 0, err


def test_a_reader_that_goes_away_is_no_traceback(files):
    """``localize LOG --json | head -c 1``: the pipe closed before the estimate is written ends
    quietly."""
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mission.cli.localize",
            str(files["log"]),
            "--method",
            "centroid",
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    p.stdout.close()  # before anything is written
    _, err = p.communicate(timeout=120)
    assert b"Traceback" not in err and p.returncode == 141, err
