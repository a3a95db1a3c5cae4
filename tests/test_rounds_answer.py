"""The adaptive flight's answer (``mission.localize.rounds_answer``): candidates from the survey,
weighed by the rounds' held-out RSS (issue 33 item 1)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import mission.localize.rounds_answer as ra
from mission.adaptive.planner import flown_ahead, survey_profile, survey_spec
from mission.adaptive.simflight import FlightWorld, SimLog
from mission.flight import live
from mission.flightlog import ADAPTIVE, MISSION, TAKEOFF
from mission.localize.rounds_answer import rounds_answer, rounds_scores, survey_and_rounds
from mission.spec import load_mission
from mission.trajectory.kinematics import plan_profile
from mission.workshop.dataset_config import DatasetConfig
from mission.workshop.flight_draws import FlightSimulator

ADAPTIVE_MISSION = "missions/spiral_adaptive.yaml"


def _square(centre: np.ndarray, half: float, z: float) -> np.ndarray:
    """A closed square (5, 3) of half side ``half`` around ``centre`` at height ``z``."""
    x, y = centre[:2]
    xs = np.array([x - half, x + half, x + half, x - half, x - half])
    ys = np.array([y - half, y - half, y + half, y + half, y - half])
    return np.column_stack([xs, ys, np.full(5, z)])


def _flight(
    repo_dir, round_at: str, seed: int = 3, drag: float | None = None
) -> tuple[SimLog, object, np.ndarray]:
    """A 200 s survey of the spiral, then one 20 m square at 15 m around the transmitter
    (``round_at`` "truth") or 80 m east of it ("elsewhere"), the mission's own physics; ``drag``:
    the vehicle's nose-down pitch per m/s (5.6: PX4 SITL's -28 deg cruise)."""
    spec = load_mission(repo_dir / ADAPTIVE_MISSION)
    rng = np.random.default_rng(seed)
    world = FlightWorld(spec, None, rng)
    cfg = dataclasses.replace(spec.sim_config(), dt_s=0.2)
    if drag is not None:
        kin = dataclasses.replace(cfg.kinematics, drag_pitch_deg_per_mps=drag)
        cfg = dataclasses.replace(cfg, kinematics=kin)
    sv = survey_profile(spec, 200.0).vertices
    home = np.asarray(spec.home_enu, dtype=float)
    log = SimLog()
    climb = [home, np.array([home[0], home[1], sv[0][2]])]
    log.fly(np.vstack([*climb, sv]), [TAKEOFF] + [MISSION] * len(sv), world, cfg, rng)
    centre = world.tx[:2] + (np.array([80.0, 0.0]) if round_at == "elsewhere" else 0.0)
    sq = _square(centre, 20.0, 15.0)
    log.fly(np.vstack([sv[-1], sq]), [ADAPTIVE] * len(sq), world, cfg, rng)
    return log, spec, np.asarray(world.tx[:2], dtype=float)


@pytest.mark.parametrize("round_at", ["truth", "elsewhere"])
def test_the_rounds_support_the_true_position_over_a_wrong_one(repo_dir, round_at):
    """Rounds flown over the transmitter confirm it; rounds flown over a wrong candidate refute
    that one: either way the held-out rounds score the true position higher."""
    log, spec, tx = _flight(repo_dir, round_at)
    flight = log.flight_log(spec, spec.adaptive)
    survey, rounds = survey_and_rounds(flight)
    assert rounds.any() and (~rounds).any() and len(survey) == int((~rounds).sum())
    # the settings flown, recorded as fly-mission records them (RoundsRunner.trajectory_meta)
    assert flight.meta["trajectory"]["adaptive"] == dataclasses.asdict(spec.adaptive)
    lpd = rounds_scores(survey, flight.select(rounds), np.array([tx, tx + [80.0, 0.0]]), 1.5)
    assert lpd[0] > lpd[1] + 1.0


def test_rounds_answer_weighs_the_live_method_and_the_survey_default(repo_dir, monkeypatch):
    """Where the networks' physics does not judge, the answer is the candidate with the most
    held-out evidence, both candidates are listed with weights summing to one, and the regions are
    the live method's."""
    monkeypatch.setattr(ra, "PHYSICS_RMS_DB", -np.inf)
    log, spec, tx = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    est = rounds_answer(flight, spec.field.origin, spec.field.rover_area)
    # the two the rounds weigh, most weight first, then the survey network (the judge's only)
    scored, judged_only = est.candidates[:2], est.candidates[2:]
    assert est.method == "rounds" and len(judged_only) == 1
    assert sum(c.weight for c in scored) == pytest.approx(1.0)
    assert judged_only[0].weight is None and judged_only[0].evidence is None
    assert judged_only[0].line().endswith("(not scored)")
    top = est.candidates[0]
    assert top.evidence == 0.0 and (est.x_m, est.y_m) == (top.x_m, top.y_m)
    assert {c.source.split(",")[0] for c in scored} == {"selfcal", "onnx"}
    _regions_are_the_live_posterior_at_adaptive_masses(est, judged=False)
    assert np.hypot(*(np.array([est.x_m, est.y_m]) - tx)) < 30.0


def test_the_series_keeps_the_live_methods_area_for_the_planner(repo_dir, monkeypatch):
    """A series entry of an adaptive flight's answer carries the printed 90 % area and the live
    method's own (``live_area_m2``), on which the planner stops, as the benchmark's simulator
    does; an entry of any other method has no second area."""
    monkeypatch.setattr(ra, "PHYSICS_RMS_DB", np.inf)  # judged: masses far from the live ones
    log, spec, _ = _flight(repo_dir, "truth")
    est = rounds_answer(
        log.flight_log(spec, spec.adaptive), spec.field.origin, spec.field.rover_area
    )
    d = live.summary(est, 100.0)
    own = est.components["selfcal"].region(0.9).area_m2
    assert d["area_m2"] == round(est.region(0.9).area_m2, 1) != d["live_area_m2"]
    assert d["live_area_m2"] == round(own, 1)
    assert "live_area_m2" not in live.summary(est.components["selfcal"], 100.0)


def _regions_are_the_live_posterior_at_adaptive_masses(est, judged: bool) -> None:
    """The answer's regions: the live method's posterior, cut at the masses calibrated on adaptive
    flights for the judge's verdict; a larger mass never gives a smaller set."""
    live = est.components["selfcal"]
    assert est.posterior is live.posterior
    assert [r.level for r in est.regions] == [r.level for r in live.regions] == [0.5, 0.9]
    for r, lr in zip(est.regions, live.regions, strict=True):
        assert r.mass == ra.REGION_MASS[judged][r.level]
        if r.mass >= lr.mass:
            assert r.area_m2 >= lr.area_m2
        else:
            assert r.area_m2 <= lr.area_m2
    assert est.regions[0].area_m2 <= est.regions[1].area_m2


@pytest.mark.parametrize("judged", [True, False])
def test_without_rounds_the_live_method_answers(repo_dir, monkeypatch, judged):
    """Before any round (the survey so far) the live method answers, with a note; where the
    networks' physics explains the survey it also names the candidate it explains best
    (``JUDGED_PICK``, where the planner may fly first), in the series entry too. A log without
    phases has no survey."""
    monkeypatch.setattr(ra, "PHYSICS_RMS_DB", ra.PHYSICS_RMS_DB if judged else -np.inf)
    log, spec, tx = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    survey = flight.select(np.asarray(flight["phase"]).astype(str) != ADAPTIVE)
    assert not survey_and_rounds(survey)[1].any()
    est = rounds_answer(survey, spec.field.origin, spec.field.rover_area)
    assert est.method == "selfcal" and "no adaptive round" in est.extras["note"]
    pick = est.extras.get(ra.JUDGED_PICK)
    d = live.summary(est, 100.0)
    if judged:  # the mission's own physics: a network's candidate, near the transmitter
        assert pick is not None and np.hypot(*(np.array(pick) - tx)) < 20.0
        assert d[ra.JUDGED_PICK] == [round(v, 1) for v in pick]
    else:
        assert pick is None and ra.JUDGED_PICK not in d
    no_phase = flight.select(np.ones(len(flight), bool))
    del no_phase.columns["phase"]
    assert survey_and_rounds(no_phase) is None


def test_a_dataset_of_an_adaptive_mission_flies_its_survey(repo_dir):
    """``rfsl dataset`` of an adaptive mission simulates the survey only (the rounds are planned in
    flight): the simulator's path is the survey's, ``survey_s`` long; a fixed mission is whole."""
    spec = load_mission(repo_dir / ADAPTIVE_MISSION)
    sim = FlightSimulator(DatasetConfig(mission=str(repo_dir / ADAPTIVE_MISSION), n=1))
    wps = sim.spec.waypoints_enu()
    assert np.array_equal(wps, survey_spec(spec, spec.adaptive.survey_s).waypoints_enu())
    t = plan_profile(wps, sim.spec.kinematics()).duration_s
    whole = plan_profile(spec.waypoints_enu(), spec.kinematics()).duration_s
    assert abs(t - spec.adaptive.survey_s) < 5.0 < whole - t
    fixed = load_mission(repo_dir / "missions" / "spiral.yaml")
    assert flown_ahead(fixed) is fixed
    off = dataclasses.replace(spec, adaptive=dataclasses.replace(spec.adaptive, enabled=False))
    assert flown_ahead(off) is off


def test_physics_rms_is_the_noise_at_the_transmitter(repo_dir):
    """``physics_rms_db``: under the networks' own physics (the mission's e2r source, 1 dB noise)
    the flight departs from the prediction at the transmitter by about the noise, 30 m off by more,
    80 m off by far more; a constant receiver offset changes nothing."""
    log, spec, tx = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    xy = np.array([tx, tx + [30.0, 0.0], tx + [80.0, 0.0]])
    rms = ra.physics_rms_db(flight, xy, spec.source.tx_height_m)
    assert 0.7 < rms[0] < 1.5 and rms[0] < rms[1] < rms[2] and rms[2] > 3 * rms[0]
    shifted = flight.select(np.ones(len(flight), bool))
    shifted.columns["rss_dbm"] = np.asarray(shifted["rss_dbm"]) - 23.0
    assert ra.physics_rms_db(shifted, xy, spec.source.tx_height_m) == pytest.approx(rms)


@pytest.mark.parametrize("holds", [True, False])
def test_the_networks_physics_judges_where_it_holds(repo_dir, monkeypatch, holds):
    """Under the threshold the candidate the networks' physics explains best answers, said in a
    note; above it the rounds choose as before."""
    log, spec, _ = _flight(repo_dir, "elsewhere")
    flight = log.flight_log(spec, spec.adaptive)
    monkeypatch.setattr(ra, "PHYSICS_RMS_DB", np.inf if holds else -np.inf)
    est = rounds_answer(flight, spec.field.origin, spec.field.rover_area)
    rms = est.extras["physics_rms_db"]
    listed = est.extras["candidates"]
    # today's two candidates and the shipped survey network, judged together
    assert len(rms) == len(listed) == len(est.candidates) == 3
    _regions_are_the_live_posterior_at_adaptive_masses(est, judged=holds)
    if holds:
        k = int(np.argmin(rms))
        assert (round(est.x_m, 2), round(est.y_m, 2)) == (listed[k]["x_m"], listed[k]["y_m"])
        assert "networks' physics explains" in est.extras["note"]
        assert est.extras[ra.JUDGED_PICK] == [est.x_m, est.y_m]
    else:
        assert ra.JUDGED_PICK not in est.extras
        top = max(listed[:2], key=lambda c: c["weight"])
        assert (round(est.x_m, 2), round(est.y_m, 2)) == (top["x_m"], top["y_m"])


@pytest.mark.parametrize("judged", [True, False])
def test_the_survey_network_answers_through_the_judge_only(repo_dir, monkeypatch, judged):
    """The survey network (``SURVEY_NETWORK``, shipped) is a third candidate for the networks'
    physics: placed at the true transmitter, the judge takes it, with a note naming it; with the
    judge off it never answers (the rounds weigh today's two candidates only), and it is listed
    with its residual either way."""
    assert ra.shipped_model(ra.SURVEY_NETWORK) is not None
    log, spec, tx = _flight(repo_dir, "elsewhere")
    flight = log.flight_log(spec, spec.adaptive)
    real = ra.survey_network

    def at_truth(survey, origin, tx_height_m):
        est = real(survey, origin, tx_height_m)
        assert est is not None and est.method == "onnx"
        return dataclasses.replace(est, x_m=float(tx[0]), y_m=float(tx[1]))

    monkeypatch.setattr(ra, "survey_network", at_truth)
    monkeypatch.setattr(ra, "PHYSICS_RMS_DB", ra.PHYSICS_RMS_DB if judged else -np.inf)
    est = rounds_answer(flight, spec.field.origin, spec.field.rover_area)
    listed, rms = est.extras["candidates"], est.extras["physics_rms_db"]
    assert listed[2]["source"] == "onnx survey network, survey" and len(rms) == 3
    assert "onnx survey network (survey)" in est.components
    assert rms[2] == min(rms) and rms[2] < 2.0  # the mission's 1 dB noise at the transmitter
    at = (round(est.x_m, 2), round(est.y_m, 2))
    if judged:
        assert at == (listed[2]["x_m"], listed[2]["y_m"]) and est.model == listed[2]["source"]
        assert "at onnx survey network, survey" in est.extras["note"]
    else:
        assert at in {(c["x_m"], c["y_m"]) for c in listed[:2]}
        assert est.model != listed[2]["source"]


@pytest.mark.parametrize("drag", [None, 5.6])
def test_a_survey_flown_nose_down_routes_to_the_tilt_survey_network(repo_dir, monkeypatch, drag):
    """A survey cruising at -28 deg (outside ``rfsl_survey_e2r``'s span) gets the survey network
    trained nose down (``SURVEY_TILT_NETWORK``, benchmarks/score_survey_tilt.py's third rule), a
    level survey keeps ``rfsl_survey_e2r``, and without the tilt network's file every survey keeps
    it. (Its accuracy is the rule's business: this 200 s survey sampled every 0.2 s is far from
    what either network was trained on.)"""
    if ra.shipped_model(ra.SURVEY_TILT_NETWORK) is None:
        pytest.skip("no survey tilt network")
    log, spec, _ = _flight(repo_dir, "truth", drag=drag)
    survey, _ = survey_and_rounds(log.flight_log(spec, spec.adaptive))
    pitch = np.median(np.asarray(survey["pitch_deg"], dtype=float))
    assert (pitch < -20.0) == (drag is not None)
    est = ra.survey_network(survey, spec.field.origin, 1.5)
    want = ra.SURVEY_NETWORK if drag is None else ra.SURVEY_TILT_NETWORK
    assert Path(est.model).name == want
    monkeypatch.setattr(ra, "SURVEY_TILT_NETWORK", "absent_survey_tilt.onnx")
    assert Path(ra.survey_network(survey, spec.field.origin, 1.5).model).name == ra.SURVEY_NETWORK
