"""``rfsl rss``: link budget CLI, its output and its one-line errors (exit 2)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from mission.cli.main import main
from mission.physics.constants import SPEED_OF_LIGHT
from mission.physics.propagation import MODEL_ALIASES, canonical_model_name


def test_free_space_value(capsys):
    assert (
        main(
            [
                "rss",
                "--model",
                "free-space",
                "--antenna",
                "isotropic",
                "--tx",
                "0,0,30",
                "--rx",
                "100,0,30",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    lam = SPEED_OF_LIGHT / 3.32e9
    assert float(out.split()[0]) == pytest.approx(
        41 + 20 * math.log10(lam / (4 * math.pi * 100)), abs=0.01
    )


def test_json_and_explain(capsys):
    assert (
        main(
            [
                "rss",
                "--model",
                "e2r",
                "--tx",
                "0,0,1.5",
                "--rx",
                "120,40,30",
                "--attitude",
                "2,-3,90",
                "--beta",
                "2.5",
                "--json",
                "--explain",
            ]
        )
        == 0
    )
    d = json.loads(capsys.readouterr().out)
    assert d["model"] == "e2r" and "leg_shadowing" in d["effects"]
    assert d["explain"]["rss_dbm"] == pytest.approx(d["rss_dbm"], abs=1e-9)
    assert d["explain"]["d_los"] == pytest.approx(math.sqrt(120**2 + 40**2 + 28.5**2))
    assert (
        main(["rss", "--tx", "0,0,1.5", "--rx", "120,40,30", "--explain", "--antenna", "measured"])
        == 0
    )
    out = capsys.readouterr().out
    assert "ground_reflection" in out and "Gamma" in out and "leg_shadowing" in out


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--tx", "1,2", "--rx", "0,0,30"], "--tx"),
        (["--tx", "1,2,a", "--rx", "0,0,30"], "--tx"),
        (["--tx", "1,2,3", "--rx", "0,0,30", "--attitude", "1,2"], "--attitude"),
        (["--tx", "1,2,3", "--rx", "0,0,30", "--antenna", "/no/such/pattern.csv"], "pattern.csv"),
    ],
)
def test_bad_input_exit_2(argv, needle, capsys):
    assert main(["rss", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1


def test_malformed_pattern_csv(tmp_path, capsys):
    f = tmp_path / "p.csv"
    f.write_text("el\\az,0,90\n-90,1,2\n90,1,oops\n")
    assert main(["rss", "--tx", "1,2,3", "--rx", "0,0,30", "--antenna", str(f)]) == 2
    err = capsys.readouterr().err
    assert "p.csv" in err and "row 3" in err


def test_subprocess_exit_code():
    root = Path(__file__).resolve().parents[1]
    r = subprocess.run(
        [sys.executable, "-m", "mission.cli.main", "rss", "--tx", "1,2", "--rx", "0,0,30"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    assert r.stderr.strip().startswith("error:") and "Traceback" not in r.stderr


def test_model_aliases_that_make_model_accepts_are_accepted(capsys) -> None:
    """One home for model names: the CLI takes every alias make_model takes (e.g. fs, two_ray) and
    folds it."""
    for alias, name in MODEL_ALIASES.items():
        assert canonical_model_name(alias.upper()) == name
    assert main(["rss", "--model", "FS", "--tx", "0,0,1.5", "--rx", "30,40,30"]) == 0
    assert main(["rss", "--model", "two_ray", "--tx", "0,0,1.5", "--rx", "30,40,30"]) == 0
