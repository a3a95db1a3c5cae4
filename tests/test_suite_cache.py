"""A benchmark cache written by other simulator code is never read silently: its fingerprint is
checked."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest
from _bad_input import run_cli

from mission.cli.main import main as rfsl_main
from mission.workshop.evaluate_suite import evaluate_suite
from mission.workshop.suite import unseen_flight
from mission.workshop.suite_cache import (
    FINGERPRINT_SCHEME,
    flight_fingerprint,
    read_suite,
    write_suite,
)

SEED = 31


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    """A tiny suite (2 flights) written by the current code."""
    d = tmp_path_factory.mktemp("suite") / "s"
    write_suite(d, 2, seed=SEED)
    return d


def _edited(src: Path, dst: Path, edit) -> Path:
    """A copy of the suite folder ``src`` at ``dst`` with its manifest changed by
    ``edit(manifest)``."""
    dst.mkdir()
    for p in src.iterdir():
        (dst / p.name).write_bytes(p.read_bytes())
    man = json.loads((src / "suite.json").read_text())
    edit(man)
    (dst / "suite.json").write_text(json.dumps(man))
    return dst


def _tamper(man: dict) -> None:
    man["fingerprint"]["sha256"] = "0" * 64


def test_fresh_suite_checks_clean(suite):
    man = read_suite(suite).manifest
    assert man["fingerprint"]["flight"] == 0 and man["fingerprint"]["scheme"] == FINGERPRINT_SCHEME
    assert man["fingerprint"]["sha256"] == flight_fingerprint(unseen_flight(SEED, 0))
    assert read_suite(suite).check_current() is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rows, _ = evaluate_suite(["strongest"], 2, suite_dir=suite, workers=1)
    assert rows[0].summary()["n"] == 2


def test_fingerprint_sees_a_changed_flight():
    f = unseen_flight(SEED, 0)
    f.log.columns["rss_dbm"] = f.log.columns["rss_dbm"] + 0.5  # e.g. a changed path gain
    assert flight_fingerprint(f) != flight_fingerprint(unseen_flight(SEED, 0))
    assert flight_fingerprint(unseen_flight(SEED, 1)) != flight_fingerprint(unseen_flight(SEED, 0))


def test_edited_or_missing_fingerprint_warns(suite, tmp_path):
    edited = _edited(suite, tmp_path / "edited", _tamper)
    text = read_suite(edited).check_current()
    assert text is not None and "\n" not in text
    assert "fingerprint of flight 0 differs" in text and str(edited) in text
    assert (
        f"rfsl dataset --suite unseen --logs --n 2 --seed {SEED} --out {edited} --overwrite" in text
    )
    old = _edited(suite, tmp_path / "old", lambda m: m.pop("fingerprint"))
    text = read_suite(old).check_current()
    assert text is not None and "\n" not in text and "no fingerprint" in text and str(old) in text
    with pytest.warns(UserWarning, match="fingerprint"):
        evaluate_suite(["strongest"], 1, suite_dir=old, workers=1)
    seen: list[str] = []
    evaluate_suite(["strongest"], 1, suite_dir=edited, workers=1, warn=seen.append)
    assert len(seen) == 1 and "differs" in seen[0]


def test_cli_prints_one_warning_line_and_scores(suite, tmp_path, capsys):
    edited = _edited(suite, tmp_path / "edited", _tamper)
    report = tmp_path / "r.json"
    argv = [
        "evaluate",
        "--suite-dir",
        edited,
        "--methods",
        "strongest",
        "--n",
        "1",
        "--workers",
        "1",
        "--out",
        report,
    ]
    rc, out, err = run_cli(rfsl_main, argv, capsys)
    assert rc == 0, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(
        f"warning: {edited} was written by other simulator code"
    )
    assert "strongest" in out
    assert "differs" in json.loads(report.read_text())["warnings"][0]
    rc, out, err = run_cli(
        rfsl_main,
        ["evaluate", "--suite-dir", suite, "--methods", "strongest", "--n", "1", "--workers", "1"],
        capsys,
    )
    assert rc == 0 and "warning" not in err, err
