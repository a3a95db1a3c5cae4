"""Shipped networks and missions: found in a source checkout and, after a plain (non-editable)
build, inside the installed package, so that an installed ``localize`` runs the shipped default
rather than a weaker fallback."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest
from _localize_helpers import write_synthetic_log

from mission.localize.api import FUSION_MODEL_NAME, shipped_model
from mission.shipped import PACKAGE_DIR, missions_dir, models_dir, shipped_dir
from mission.spec import DEFAULT_MISSION


def test_checkout_folders(repo_dir):
    assert models_dir() == repo_dir / "models" and missions_dir() == repo_dir / "missions"

    assert shipped_model(FUSION_MODEL_NAME) == repo_dir / "models" / FUSION_MODEL_NAME
    assert shipped_model("no_such_model.onnx") is None
    assert DEFAULT_MISSION == repo_dir / "missions" / "spiral.yaml"
    assert not (PACKAGE_DIR / "data" / "models").exists(), (
        "the installed copy must not appear in a checkout"
    )


def test_installed_copy_wins(tmp_path):
    pkg = tmp_path / "site" / "mission"
    # no copy: the folder beside the package
    assert shipped_dir("models", pkg) == tmp_path / "site" / "models"
    (pkg / "data" / "models").mkdir(parents=True)
    assert shipped_dir("models", pkg) == pkg / "data" / "models"
    assert shipped_dir("missions", pkg) == tmp_path / "site" / "missions"
    with pytest.raises(ValueError, match="unknown shipped folder"):
        shipped_dir("datasets", pkg)


@pytest.mark.slow
def test_plain_build_localizes_with_shipped_default(repo_dir, tmp_path):
    """setup.py's build step copies models/ and missions/ into the built package; run from that
    build alone (no checkout beside it), ``localize`` uses the shipped default network and the
    shipped spiral mission."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "LICENSE"):
        shutil.copy2(repo_dir / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("mission", "sitl", "models", "missions"):
        shutil.copytree(repo_dir / name, src / name, ignore=ignore)
    lib = tmp_path / "lib"
    subprocess.run(
        [sys.executable, "setup.py", "-q", "build_py", "--build-lib", str(lib)],
        cwd=src,
        check=True,
        capture_output=True,
    )
    assert (lib / "mission" / "data" / "models" / "rfsl_spiral_e2r.onnx").is_file()
    assert (lib / "mission" / "data" / "missions" / "spiral.yaml").is_file()
    log = write_synthetic_log(tmp_path / "run" / "flight.csv", (150.0, 120.0, 1.5))
    env = {**os.environ, "PYTHONPATH": str(lib)}
    code = (
        "import json, sys; from mission.cli.localize import main; import mission.spec as s; "
        "print(json.dumps({'mission_file': str(s.DEFAULT_MISSION)})); sys.exit(main(sys.argv[1:]))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(log), "--json"],
        cwd=tmp_path / "run",
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    where, est = json.loads(out[0]), json.loads("\n".join(out[1:]))
    assert where["mission_file"] == str(lib / "mission" / "data" / "missions" / "spiral.yaml")
    # a simulated log without a trajectory: the simulated-log route to the shipped rfsl_default,
    # found in the build
    assert (est["method"], est["model"]) == ("onnx", "rfsl_default.onnx"), est["method_choice"]
