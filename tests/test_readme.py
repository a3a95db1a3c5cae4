"""README.md is for users: short, its test command is the one CI runs, its links and commands
exist."""

from __future__ import annotations

import importlib
import re

import pytest

from mission.cli.main import SUBCOMMANDS
from mission.errors import InputError


@pytest.fixture(scope="module")
def readme(repo_dir) -> str:
    return (repo_dir / "README.md").read_text()


def _code_lines(text: str) -> list[str]:
    """Lines of the ```bash blocks."""
    return [
        ln for block in re.findall(r"```bash\n(.*?)```", text, re.S) for ln in block.splitlines()
    ]


def test_short_and_without_history(readme):
    assert len(readme.splitlines()) < 120
    assert not re.search(r"\b[Ss]top \d+|\bissue \d+|#\d+\b", readme), (
        "no development history in the README"
    )


def test_test_command_is_what_ci_runs(readme, repo_dir):
    (cmd,) = [ln for ln in _code_lines(readme) if "pytest" in ln]
    # CI makes its fresh venv on lines of its own
    venv, rest = (part.strip() for part in cmd.split("&&", 1))
    ci = (repo_dir / ".ci" / "run").read_text().splitlines()
    assert venv == "python3 -m venv .venv" and venv in ci and rest in ci and "--all" in rest


def test_links_and_picture_exist(readme, repo_dir):
    targets = re.findall(r"\]\(([^)#]+)\)", readme)
    assert targets and "docs/localize-real-flight.png" in targets
    for t in targets:
        assert (repo_dir / t).exists(), t
    assert (repo_dir / "docs" / "localize-real-flight.png").stat().st_size < 100_000, (
        "keep the picture small"
    )


def test_commands_name_real_subcommands_and_files(readme, repo_dir):
    for ln in _code_lines(readme):
        for sub in re.findall(r"\brfsl (\w+)", ln):
            assert sub in SUBCOMMANDS, ln
        for path in re.findall(r"\b(missions/\w+\.yaml)", ln):
            assert (repo_dir / path).is_file(), ln


def test_exit_code_table_matches_the_code(readme):
    """The README's exit-code table names every code the commands return: bad input, and each flight
    ``EXIT_*`` constant (a new one needs its column)."""
    mods = []
    for name in ("mission.flight.context", "mission.flight.tasks"):  # where the flight's codes live
        try:
            mods.append(importlib.import_module(name))
        except ImportError:
            continue
    codes_in_code = {
        v for m in mods for k, v in vars(m).items() if k.startswith("EXIT_") and isinstance(v, int)
    }
    (row,) = [ln for ln in readme.splitlines() if ln.startswith("| exit |")]
    codes = [int(c) for c in row.strip("| ").split("|")[1:]]
    assert codes == sorted(codes_in_code | {InputError.exit_code}), codes_in_code
    means = next(ln for ln in readme.splitlines() if ln.startswith("| means |")).split("|")[2:-1]
    assert (
        "bad input" in means[codes.index(InputError.exit_code)]
        and "dead link" in means[codes.index(3)]
    )
    assert "interrupted" in means[codes.index(130)]
