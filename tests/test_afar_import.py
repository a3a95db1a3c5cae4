"""AFAR MAT importer: a small synthetic MAT fixture (scipy.io.savemat) and, when present, the real
files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio

from mission.cli.main import main as rfsl
from mission.errors import InputError
from mission.flightlog import FlightLog, read_flight_log
from mission.flightlog.schema import QUALITY_COLUMN, SOUNDER_LOCK_DB
from mission.gap.align import afar2023_flights
from mission.geo import afar_field
from mission.importers.afar import convert_afar_mat, import_afar_mat
from mission.localize import Estimate
from mission.localize.api import _lock_note, localize_log
from mission.localize.preprocess import select_samples

SHARED = Path(__file__).parents[1] / ".." / "shared" / "data" / "afar2023" / "mat"


def make_mat(
    path: Path, n: int = 200, shuffle: bool = False, dup: bool = False, drop: str | None = None
) -> Path:
    t = 1.70247e9 + np.arange(n) * 0.0327
    if dup:
        t[50] = t[49]
        t[80] = t[79] + 2e-5
    d = {
        "timestamp_power": t,
        "mX": -78.6975 + np.linspace(0, 1e-3, n),
        "mY": 35.728 + np.zeros(n),
        "mZ": np.linspace(0, 30, n),
        "mRoll": np.zeros(n),
        "mPitch": np.ones(n),
        "mYaw": np.full(n, 370.0),
        "mpower": np.linspace(-30, 10, n),
        "mquality": np.ones(n),
    }
    if shuffle:
        p = np.random.default_rng(0).permutation(n)
        d = {k: v[p] for k, v in d.items()}
    if drop:
        d.pop(drop)
    sio.savemat(path, {k: v.reshape(-1, 1) for k, v in d.items()})
    return path


def test_fixture_roundtrip(tmp_path):
    mat = make_mat(tmp_path / "results_useful_ori_exp_999_loc_1.mat")
    res = import_afar_mat(mat, tmp_path / "out", truth=(35.728, -78.697))
    log = read_flight_log(res.out_path)
    assert len(log) == 200 and log["t_s"][0] == 0.0
    assert log.meta["rss_source"] == {
        "kind": "real",
        "receiver": "AERPAW channel sounder",
        "calibrated": False,
    }
    assert log.meta["truth"] == {"lat_deg": 35.728, "lon_deg": -78.697, "height_m": 1.5}
    assert log.origin == afar_field().origin
    np.testing.assert_allclose(log["alt_m"], log["rel_alt_m"])
    np.testing.assert_allclose(log["rel_alt_m"][-1], 30.0)
    assert np.all(log["yaw_deg"] < 360.0)


def test_quality_carried_when_present(tmp_path):
    """``mquality`` becomes the column ``rss_quality_db`` row for row with the power (through
    sorting and dropped duplicates); a file without it imports without the column; a value no
    sounder gives reads as unknown (the sample kept); a variable of another length is refused
    naming it."""
    mat = make_mat(tmp_path / "q.mat", shuffle=True, dup=True)
    d = sio.loadmat(mat)
    d["mquality"] = 50.0 + d["mpower"] / 2.0  # a known function of the power, to follow the rows
    sio.savemat(mat, {k: v for k, v in d.items() if not k.startswith("__")})
    res = import_afar_mat(mat, tmp_path / "out", truth=(35.728, -78.697))
    log = read_flight_log(res.out_path)
    np.testing.assert_allclose(log[QUALITY_COLUMN], 50.0 + log["rss_dbm"] / 2.0, atol=0.01)
    plain = convert_afar_mat(make_mat(tmp_path / "p.mat", drop="mquality"))
    assert QUALITY_COLUMN not in plain.log.columns and len(plain.log) == 200
    d["mquality"][[0, 5], 0] = [np.inf, 1e300]  # no sounder reads these: unknown, with a note
    sio.savemat(mat, {k: v for k, v in d.items() if not k.startswith("__")})
    res = convert_afar_mat(mat)
    assert np.isnan(res.log[QUALITY_COLUMN]).sum() == 2 and len(res.log) == 198
    assert any("2 quality value(s)" in n for n in res.notes)
    d["mquality"] = d["mquality"][:-1]
    sio.savemat(mat, {k: v for k, v in d.items() if not k.startswith("__")})
    with pytest.raises(InputError, match="mquality"):
        convert_afar_mat(mat)


def test_no_truth_guessed_from_name(tmp_path):
    res = convert_afar_mat(make_mat(tmp_path / "results_useful_ori_exp_288_loc_3.mat"))
    assert "truth" not in res.log.meta


def test_unsorted_and_duplicates(tmp_path):
    res = convert_afar_mat(make_mat(tmp_path / "a.mat", shuffle=True, dup=True))
    assert np.all(np.diff(res.log["t_s"]) > 0)
    assert len(res.log) == 198
    text = " ".join(res.notes)
    assert "sorted" in text and "duplicate" in text and "1 ms" in text


def test_bad_files(tmp_path):
    bad = tmp_path / "bad.mat"
    bad.write_text("not a mat file")
    with pytest.raises(InputError, match="bad.mat"):
        convert_afar_mat(bad)
    with pytest.raises(InputError, match="mpower"):
        convert_afar_mat(make_mat(tmp_path / "m.mat", drop="mpower"))
    with pytest.raises(InputError, match="nope.mat"):
        convert_afar_mat(tmp_path / "nope.mat")


def test_cli(tmp_path, capsys):
    mat = make_mat(tmp_path / "f.mat")
    assert (
        rfsl(
            ["import", "afar-mat", str(mat), "--out", str(tmp_path / "o"), "--truth", "35.7,-78.6"]
        )
        == 0
    )
    assert (tmp_path / "o" / "f.csv").exists() and (tmp_path / "o" / "f.json").exists()
    assert rfsl(["import", "afar-mat", str(mat), "--out", str(tmp_path / "o")]) == 2  # exists
    assert rfsl(["import", "afar-mat", str(mat), "--out", str(tmp_path / "p"), "--truth", "x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("error:") for line in err)


@pytest.mark.real
@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared real data absent")
def test_real_files(tmp_path):
    for f in sorted(SHARED.glob("*.mat")):
        res = import_afar_mat(f, tmp_path)
        log = read_flight_log(res.out_path)
        assert len(log) > 20000
        assert 20.0 < np.median(log["rel_alt_m"]) < 40.0
        enu = log.enu()
        assert np.all(np.abs(enu[:, :2]) < 1000.0)
        # sounder quality: about 72 dB when locked, < 50 dB (lock lost) on 1-60 % of a flight
        q = log[QUALITY_COLUMN]
        assert np.isfinite(q).all() and 65.0 < np.median(q[q >= SOUNDER_LOCK_DB]) < 75.0
        assert 0.01 < np.mean(q < SOUNDER_LOCK_DB) < 0.6


@pytest.mark.real
@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared real data absent")
def test_afar_flights_without_the_samples_read_out_of_lock():
    """``afar2023_flights(lock_db=)`` withholds exactly the airborne samples under the quality;
    without it the flights are as before (every airborne sample)."""
    every = afar2023_flights(SHARED)
    locked = afar2023_flights(SHARED, lock_db=SOUNDER_LOCK_DB)
    for f, g in zip(every, locked, strict=True):
        log = convert_afar_mat(
            SHARED / f"results_useful_ori_exp_{f.name.replace('-loc', '_loc_')}.mat"
        ).log
        air = log.enu()[:, 2] > 10.0
        assert len(f) == air.sum()
        assert len(g) == (air & (log[QUALITY_COLUMN] >= SOUNDER_LOCK_DB)).sum() < len(f)


def test_lock_note_only_from_a_tenth_of_the_samples():
    """``api._lock_note``: the share is reported whenever the log carries the quality; the note
    only from ``LOCK_NOTE_SHARE`` of the samples read out of lock (NaN counts as out of lock)."""
    for q, share, noted in (
        ([72.0] * 19 + [40.0], 0.05, False),
        ([72.0] * 8 + [40.0, np.nan], 0.2, True),
    ):
        est = Estimate(0.0, 0.0, "selfcal", "m", 0.0, 0.0)
        n = len(q)
        part = FlightLog(
            {
                "t_s": np.arange(n, dtype=float),
                "rss_dbm": np.linspace(0.0, -30.0, n),
                QUALITY_COLUMN: np.array(q),
            }
        )
        _lock_note(est, part)
        assert est.extras["out_of_lock_share"] == pytest.approx(share)
        assert (f"{100 * share:.0f} % of the samples used" in " ".join(est.notes)) == noted
        # the floor: the power of the locked row next to the one change, the last locked row
        k = next(i for i, v in enumerate(q) if not v >= SOUNDER_LOCK_DB) - 1
        floor = -30.0 * k / (n - 1)
        assert est.extras["lock_floor_db"] == pytest.approx(floor)
        assert (f"below about {floor:.0f} dB" in " ".join(est.notes)) == noted
    est = Estimate(0.0, 0.0, "selfcal", "m", 0.0, 0.0)
    _lock_note(est, FlightLog({"t_s": np.arange(3.0)}))
    assert "out_of_lock_share" not in est.extras and not est.notes


@pytest.mark.real
@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared real data absent")
def test_localize_reports_the_share_read_out_of_lock_and_answers_the_same(tmp_path):
    """On 328 loc 3 (a third read out of lock) the default's answer is the same with or without
    the quality column; with it, ``out_of_lock_share`` is the used samples' share and a note says
    so."""
    mat = SHARED / "results_useful_ori_exp_328_loc_3.mat"
    log = read_flight_log(
        import_afar_mat(mat, tmp_path, truth=(35.72985129, -78.69711002)).out_path
    )
    with_q = localize_log(log)
    bare = FlightLog(
        {k: v for k, v in log.columns.items() if k != QUALITY_COLUMN}, log.meta, log.path
    )
    without = localize_log(bare)
    assert (with_q.x_m, with_q.y_m) == (without.x_m, without.y_m)
    assert "out_of_lock_share" not in without.extras
    part, _ = select_samples(log)
    share = float(np.mean(part[QUALITY_COLUMN] < SOUNDER_LOCK_DB))
    assert with_q.extras["out_of_lock_share"] == pytest.approx(share) and 0.25 < share < 0.45
    assert "read with the receiver out of lock" in " ".join(with_q.notes)
    # the level where this flight's sounder loses lock (experiments/lock_mechanism.py: -25.7 dB)
    assert -30.0 < with_q.extras["lock_floor_db"] < -23.0
