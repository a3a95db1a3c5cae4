"""Round 4 of the gap diagnosis (issue 34): effects along time, ground- or body-fixed, one verdict
on what is left, and process-level parallelism.  Small seeded cases from the independent generator
(``_gap_synth``)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from _gap_synth import make_case

from mission.gap.candidates import select
from mission.gap.diagnose import diagnose
from mission.gap.fit import FitConfig, heldout_residuals, make_folds, rank_candidates
from mission.gap.frame import frame_test, heading_groups, resolve
from mission.gap.pipeline import Pipeline
from mission.gap.report import summary, write_report
from mission.gap.structure import WITHIN_FLIGHT, structure_verdict
from mission.gap.temporal import MIN_EVENT_GAP_S, flight_events, time_power_statement
from mission.gap.text import verdict_sentence
from mission.physics import Attitude, make_model
from mission.robust import offset_residual
from mission.samples import FlightSamples


def _flights(effect: str, seed: int, dt: float = 1.0, **kw) -> tuple[list[FlightSamples], dict]:
    raw, truth = make_case(effect, seed, dt=dt, **kw)
    return [
        FlightSamples(
            name=f"synth{k}",
            t_s=f["t"],
            enu_m=f["pos"],
            attitude_rad=f["att"],
            rss_dbm=f["rss"],
            tx_enu_m=f["tx"],
            phase=f.get("phase"),
        )
        for k, f in enumerate(raw)
    ], truth


def _base() -> Pipeline:
    return Pipeline(make_model("two-ray", pattern="dipole").with_effect(Attitude()))


def _rank(flights, names, cfg, pipe=None):
    folds = make_folds(flights, cfg)
    pipes = [pipe or _base()] * len(folds)
    base = heldout_residuals(pipes, flights, folds, cfg)
    return {
        r.name: r
        for r in rank_candidates(
            pipes, flights, folds, select(names), cfg, np.random.default_rng(cfg.seed), base
        )
    }


def test_flight_events_find_turns_and_phase_changes():
    fl, truth = _flights("step", 2)
    for f in fl:
        ev = flight_events(f)
        assert len(ev) >= 1 and np.all(np.diff(ev) >= MIN_EVENT_GAP_S)
    # the step sits at an event of every flight (a lawnmower turn, or the spiral's logged phase
    # change)
    for f, ts in zip(fl, truth["step_s"], strict=True):
        assert np.min(np.abs(flight_events(f) - ts)) <= f.t_s[1] - f.t_s[0] + 1e-9


def test_time_drift_finds_a_step_and_nothing_in_noise():
    cfg = FitConfig(seed=1, fit_max_samples=800)
    fl, truth = _flights("step", 1)
    r = _rank(fl, ["time_drift", "path_gain_slope"], cfg)
    assert (
        r["time_drift"].significant
        and r["time_drift"].rel_reduction > 2 * r["path_gain_slope"].rel_reduction
    )
    fl0, _ = _flights("none", 1)
    assert not _rank(fl0, ["time_drift"], cfg)["time_drift"].significant


def test_time_power_statement_blocks_and_flights():
    fl, _ = _flights("none", 3)
    res = [offset_residual(f.rss_dbm, _base().predict(f), False, "l2") for f in fl]
    cfg = FitConfig(seed=3, fit_max_samples=800)
    blocks = time_power_statement(fl, res, make_folds(fl, cfg), cfg, 10, "blocks")
    assert math.isfinite(blocks["detectable_db"]) and blocks["detectable_db"] <= 3.0  # 1 dB noise
    cf = FitConfig(split="flights")
    whole = time_power_statement(fl, res, make_folds(fl, cf), cf, 10, "flights")
    assert whole["detectable_db"] == math.inf and "whole flights" in whole["statement"]


def test_heading_groups_split_a_lawnmower_by_row_direction():
    fl, _ = _flights("none", 1)
    g = heading_groups(fl[0])  # lawnmower: east- and westbound rows
    assert 0.35 < g.mean() < 0.65
    yaw = fl[0].attitude_rad[:, 2]
    east = np.abs(np.angle(np.exp(1j * (yaw - np.pi / 2)))) < 0.2
    west = np.abs(np.angle(np.exp(1j * (yaw + np.pi / 2)))) < 0.2
    assert len(set(g[east])) == 1 and len(set(g[west])) == 1 and g[east][0] != g[west][0]


@pytest.mark.parametrize(
    ("effect", "verdict"), [("ripple", "body-fixed"), ("shadowing", "ground-fixed")]
)
def test_frame_test_tells_body_from_ground(effect, verdict):
    fl, _ = _flights(effect, 2)
    out = frame_test(
        _base(), fl, "rx_gain_map", "spatial_shadowing", FitConfig(seed=2, fit_max_samples=800)
    )
    assert out["verdict"] == verdict, out["text"]


def test_resolve_gives_way_to_the_frame_winner():
    fr = {
        "body": "leg_shadowing",
        "ground": "spatial_shadowing",
        "winner": "leg_shadowing",
        "splits": {"headings": {"leg_shadowing": {"significant": False}}},
    }
    assert resolve("spatial_shadowing", [], fr) == "leg_shadowing"
    assert resolve("ground_reflection", [], fr) == "ground_reflection"
    assert resolve(None, [], fr) is None  # not significant across headings: nothing is named
    assert resolve("leg_shadowing", [], {**fr, "winner": None}) == "leg_shadowing"


def test_processes_are_bit_identical_to_one():
    fl, _ = _flights("step", 4)
    names = ["time_drift", "rx_gain_map", "path_gain_slope", "spatial_shadowing"]
    one = _rank(fl, names, FitConfig(seed=4, fit_max_samples=600))
    two = _rank(fl, names, FitConfig(seed=4, fit_max_samples=600, processes=2))
    for k in names:
        assert one[k].loss_reduction == two[k].loss_reduction and one[k].ci_lo == two[k].ci_lo
        for a, b in zip(one[k].residuals, two[k].residuals, strict=True):
            assert np.array_equal(a, b, equal_nan=True)


def test_a_whole_diagnosis_in_processes_is_bit_identical_to_one():
    """The whole diagnosis, with candidates scored as their folds arrive and the statistics after
    the ladder run as jobs in the processes, writes the very ``gap.json`` of one process."""
    fl, _ = _flights("step", 2)
    docs = []
    for processes in (1, 2):
        d = diagnose(
            fl,
            _base(),
            select(["time_drift", "path_gain_slope", "rx_gain_map"]),
            FitConfig(seed=2, fit_max_samples=600, processes=processes),
            reference=("two-ray",),
            localize=False,
        )
        docs.append(json.dumps(summary(d), sort_keys=True, default=str))
    assert docs[0] == docs[1] and '"structure"' in docs[0]


def test_one_verdict_on_what_is_left():
    along = {"correlated_fraction": 0.8, "sigma_db": 9.8, "corr_len": 20.0, "nugget_db": 5.0}
    test = {"correlated": False, "ratio": 0.93, "ratio_ci": [0.8, 1.05], "correlated_std_db": 2.0}
    assert structure_verdict(test, along) == WITHIN_FLIGHT
    assert structure_verdict({**test, "correlated": True}, along) == "correlated shadowing"
    assert structure_verdict(test, {**along, "correlated_fraction": 0.2}) == "white noise"
    st = {
        "verdict": WITHIN_FLIGHT,
        "test": test,
        "along_path": along,
        "spatial": {},
        "residual_std_db": 11.0,
    }
    s = verdict_sentence(st, 2.0)
    assert "correlated along each flight" in s and "not shown to repeat over the same ground" in s
    assert "white noise of" not in s


def test_diagnosis_report_with_a_time_rung(tmp_path):
    """The ladder adds ``time_drift`` on a gain step; the report, gap.json and the summary say
    so."""
    fl, _ = _flights("step", 1)
    d = diagnose(
        fl,
        _base(),
        select(["time_drift", "path_gain_slope"]),
        FitConfig(seed=1, fit_max_samples=800),
        reference=("two-ray",),
        localize=False,
    )
    assert [r.added for r in d.rungs][1] == "time_drift"
    write_report(d, tmp_path)
    doc = json.loads((tmp_path / "gap.json").read_text())
    assert "better explained along the flight's time than by geometry" in doc["text"]
    assert doc["ladder"][1]["added"] == "time_drift" and "time_power" in doc
