"""Terminal output reads at 80 columns: with ``COLUMNS=80`` the help of ``rfsl`` and of every subcommand, and
the output of ``rfsl rss --explain``, ``simulate``, ``replay``, ``export`` and ``import``, have no line wider
than 80 characters (paths kept short by working in the test folder; ``calibrate``'s is checked with its
real-flight test in test_selfcal)."""

from __future__ import annotations

import pytest

from mission.cli.main import SUBCOMMANDS
from mission.cli.main import main as rfsl

WIDTH = 80


def too_wide(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if len(ln) > WIDTH]


@pytest.fixture(autouse=True)
def columns_80(monkeypatch, tmp_path):
    monkeypatch.setenv("COLUMNS", str(WIDTH))
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("command", [None, *SUBCOMMANDS])
def test_help_fits(command, capsys):
    with pytest.raises(SystemExit) as e:
        rfsl([command, "--help"] if command else ["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: rfsl") and not too_wide(out), too_wide(out)


def test_calibrate_help_keeps_configuration_names_whole(capsys):
    from mission.calibrate import DEFAULT_CONFIGS

    with pytest.raises(SystemExit):
        rfsl(["calibrate", "--help"])
    words = capsys.readouterr().out.replace(",", " ").replace(")", " ").split()
    assert all(c in words for c in DEFAULT_CONFIGS), "a default configuration name is folded mid-word or missing"


def test_rss_explain_fits(capsys):
    assert rfsl(["rss", "--model", "e2r", "--tx", "100,200,1.5", "--rx", "120,180,30", "--attitude", "2,-3,90",
                 "--explain"]) == 0
    out = capsys.readouterr().out
    assert "leg_shadowing" in out and not too_wide(out), too_wide(out)


def test_simulate_replay_export_fit(repo_dir, capsys):
    mission = repo_dir / "missions" / "waypoints.yaml"
    assert rfsl(["simulate", str(mission), "--seed", "3", "--cruise-only", "--out", "f"]) == 0
    out = capsys.readouterr().out
    assert "transmitter at" in out and not too_wide(out), too_wide(out)
    log = out.rsplit("log: ", 1)[1].strip()
    assert rfsl(["replay", log]) == 0
    out = capsys.readouterr().out
    assert "rss_median_db" in out and not too_wide(out), too_wide(out)
    assert rfsl(["export", str(mission), "--format", "plan", "--out", "m.plan"]) == 0
    out = capsys.readouterr().out
    assert "wrote m.plan" in out and not too_wide(out), too_wide(out)


def test_import_fits(shared_dir, capsys):
    mat = shared_dir / "data" / "afar2023" / "mat" / "results_useful_ori_exp_328_loc_1.mat"
    assert rfsl(["import", "afar-mat", str(mat), "--out", "real"]) == 0
    out = capsys.readouterr().out
    assert "note: dropped" in out and not too_wide(out), too_wide(out)
