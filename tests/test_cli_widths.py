"""Terminal output reads at 80 columns: with ``COLUMNS=80`` the help of ``rfsl`` and of every
subcommand, and the output of ``rfsl rss --explain``, ``simulate``, ``replay``, ``export`` and
``import``, have no line wider than 80 characters (paths kept short by working in the test folder;
``calibrate``'s is checked with its real-flight test in test_selfcal)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from rich.console import Console

from mission.calibrate import DEFAULT_CONFIGS
from mission.cli.evaluate import _table
from mission.cli.gap import confusion_table
from mission.cli.main import SUBCOMMANDS
from mission.cli.main import main as rfsl
from mission.gap.selftest import WITHHELD_ALL
from mission.workshop.evaluate import Row

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
    with pytest.raises(SystemExit):
        rfsl(["calibrate", "--help"])
    words = capsys.readouterr().out.replace(",", " ").replace(")", " ").split()
    assert all(c in words for c in DEFAULT_CONFIGS), (
        "a default configuration name is folded mid-word or missing"
    )


def test_rss_explain_fits(capsys):
    assert (
        rfsl(
            [
                "rss",
                "--model",
                "e2r",
                "--tx",
                "100,200,1.5",
                "--rx",
                "120,180,30",
                "--attitude",
                "2,-3,90",
                "--explain",
            ]
        )
        == 0
    )
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


def _render(table) -> str:
    c = Console(width=WIDTH, file=io.StringIO(), record=True)
    c.print(table)
    return c.export_text()


def test_gap_selftest_confusion_keeps_every_effect_name():
    """``rfsl gap --selftest``'s confusion matrix at 80 columns: every effect name whole, nothing
    cut."""
    names = [*WITHHELD_ALL, "none"]
    text = _render(confusion_table(names, names, np.eye(len(names), dtype=int) * 2))
    assert not too_wide(text) and "…" not in text, text
    for i, name in enumerate(names):
        assert f"{i + 1:>2} {name} " in text, name


def test_evaluate_table_does_not_cut_labels():
    """``rfsl evaluate``'s table at 80 columns: a long method or test name is folded, never cut with
    '…'."""
    rows = [
        Row(
            "sim_e2r_spiral_n200_s7_with_a_long_name",
            f"onnx:rfsl_spiral_e2r_ens5_variant_{k}.onnx",
            "e2r_randomised_physics",
            "clustering3d_v2",
            [1.0, 2.0, 3.0],
        )
        for k in range(2)
    ]
    text = _render(_table(rows, "simulated test sets"))
    assert not too_wide(text) and "…" not in text, text
    cells = [ln.split("│") for ln in text.splitlines() if ln.startswith("│")]
    for col, want in ((1, rows[0].test), (2, rows[0].method + rows[1].method)):
        assert want in "".join(c[col].strip() for c in cells), text
