"""The umbrella command: every registered subcommand is importable and listed with its purpose."""

from __future__ import annotations

import subprocess
import sys

from mission.cli.main import SUBCOMMANDS, _available


def test_every_registered_subcommand_is_available():
    assert set(_available()) == set(SUBCOMMANDS)


def test_help_lists_every_subcommand_with_a_purpose():
    r = subprocess.run(
        [sys.executable, "-m", "mission.cli.main", "--help"], capture_output=True, text=True
    )
    assert r.returncode == 0
    out = " ".join(r.stdout.split())
    for name, (_, purpose) in SUBCOMMANDS.items():
        assert f"{name} {' '.join(purpose.split()[:3])}" in out, name


def test_unknown_subcommand_exit_2():
    r = subprocess.run(
        [sys.executable, "-m", "mission.cli.main", "nope"], capture_output=True, text=True
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr
