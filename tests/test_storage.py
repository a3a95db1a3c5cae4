"""Files the commands write are written whole or not at all (issue 37): under a file-size limit (a
full disk) ``rfsl import``, ``simulate``, ``export`` and ``dataset`` exit non-zero with one line,
and leave no truncated CSV beside a sidecar (which ``localize`` accepted), no partial export, no
leftover temporary file; an existing file is kept as it was.

The limit is ``RLIMIT_FSIZE`` in a child process with ``SIGXFSZ`` ignored, so a write past it fails
with EFBIG exactly where a full disk fails with ENOSPC.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio
from _bad_input import SPIRAL, mat_arrays

from mission import files
from mission.errors import InputError
from mission.flightlog import write_flight_log


def run_limited(argv: list[str], limit: int, cwd: Path) -> subprocess.CompletedProcess:
    """``rfsl argv`` in a child whose files may not grow past ``limit`` bytes."""
    code = (
        "import resource, signal, sys\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        f"resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))\n"
        "from mission.cli.main import main\n"
        f"sys.exit(main({[str(a) for a in argv]!r}))\n"
    )
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=cwd
    )


def assert_one_line_failure(r: subprocess.CompletedProcess, *names: str) -> None:
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode != 0, r.stdout
    assert len(lines) == 1, r.stderr
    for n in names:
        assert n in lines[0], lines[0]


def no_partial_files(folder: Path) -> list[str]:
    """Names under ``folder`` that a failed write must not leave: temporary parts, a CSV without its
    sidecar or a sidecar without its CSV."""
    names = {p.name for p in folder.rglob("*") if p.is_file()}
    bad = [n for n in names if n.endswith(".part")]
    bad += [n for n in names if n.endswith(".csv") and n[:-4] + ".json" not in names]
    bad += [n for n in names if n.endswith(".json") and n[:-5] + ".csv" not in names]
    return bad


@pytest.fixture(scope="module")
def mat(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("mat")
    sio.savemat(d / "f.mat", mat_arrays(2000))
    return d / "f.mat"


def test_import_under_a_full_disk_writes_nothing(tmp_path, mat):
    out = tmp_path / "logs"
    r = run_limited(["import", "afar-mat", mat, "--out", out], 16 * 1024, tmp_path)
    assert_one_line_failure(r, "f.csv", "nothing written")
    assert not list(out.glob("f.*")), list(out.iterdir())
    assert no_partial_files(out) == []


@pytest.mark.slow
def test_simulate_under_a_full_disk_writes_nothing(tmp_path):
    out = tmp_path / "sims"
    r = run_limited(["simulate", SPIRAL, "--out", out], 256 * 1024, tmp_path)
    assert_one_line_failure(r, ".csv", "too large")
    assert list(out.iterdir()) == []


def test_export_under_a_full_disk_keeps_the_old_file(tmp_path):
    out = tmp_path / "m.kml"
    out.write_text("mine")
    r = run_limited(["export", SPIRAL, "--out", out, "--overwrite"], 256, tmp_path)
    assert_one_line_failure(r, "m.kml")
    assert out.read_text() == "mine"
    assert no_partial_files(tmp_path) == []


@pytest.mark.slow
def test_dataset_under_a_full_disk_fails_in_one_line(tmp_path):
    r = run_limited(["dataset", SPIRAL, "--n", "1", "--out", tmp_path / "ds"], 8 * 1024, tmp_path)
    assert_one_line_failure(r, "chunk_00000.npz")
    assert not (tmp_path / "ds" / "manifest.json").exists()
    assert no_partial_files(tmp_path) == []


def test_writing_replaces_only_when_complete(tmp_path):
    """A failure inside the block leaves the old file and no temporary; success replaces it at
    once."""
    p = tmp_path / "a.txt"
    p.write_text("old")
    with pytest.raises(RuntimeError), files.writing(p) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk gone")
    assert p.read_text() == "old" and [q.name for q in tmp_path.iterdir()] == ["a.txt"]
    files.write_text(p, "new")
    assert p.read_text() == "new" and [q.name for q in tmp_path.iterdir()] == ["a.txt"]


def test_write_flight_log_refuses_an_existing_sidecar(tmp_path):
    """A sidecar alone (its CSV deleted or not yet written) is not replaced silently."""
    (tmp_path / "f.json").write_text(json.dumps({"mine": 1}))
    cols = {
        "t_s": np.arange(3.0),
        "lat_deg": np.full(3, 35.7),
        "lon_deg": np.full(3, -78.7),
        "alt_m": np.full(3, 30.0),
        "rel_alt_m": np.full(3, 30.0),
        "roll_deg": np.zeros(3),
        "pitch_deg": np.zeros(3),
        "yaw_deg": np.zeros(3),
        "rss_dbm": np.full(3, -50.0),
    }

    with pytest.raises(InputError, match="f.json"):
        write_flight_log(tmp_path / "f.csv", cols, {})
    assert json.loads((tmp_path / "f.json").read_text()) == {"mine": 1}
    assert not (tmp_path / "f.csv").exists()
