"""The adaptive flight's answer (``mission.localize.rounds_answer``): candidates from the survey,
weighed by the rounds' held-out RSS (issue 33 item 1)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mission.localize.rounds_answer as ra
from mission.adaptive.planner import flown_ahead, survey_profile, survey_spec
from mission.adaptive.simflight import FlightWorld, SimLog
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


def _flight(repo_dir, round_at: str, seed: int = 3) -> tuple[SimLog, object, np.ndarray]:
    """A 200 s survey of the spiral, then one 20 m square at 15 m around the transmitter
    (``round_at`` "truth") or 80 m east of it ("elsewhere"), the mission's own physics."""
    spec = load_mission(repo_dir / ADAPTIVE_MISSION)
    rng = np.random.default_rng(seed)
    world = FlightWorld(spec, None, rng)
    cfg = dataclasses.replace(spec.sim_config(), dt_s=0.2)
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
    """Where the network's physics does not hold, the answer is the candidate with the most
    held-out evidence, both candidates are listed with weights summing to one, and the regions are
    the live method's."""
    monkeypatch.setattr(ra, "PHYSICS_SPREAD_DB", -np.inf)
    log, spec, tx = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    est = rounds_answer(flight, spec.field.origin, spec.field.rover_area)
    assert est.method == "rounds" and len(est.candidates) == 2
    assert sum(c.weight for c in est.candidates) == pytest.approx(1.0)
    top = est.candidates[0]
    assert top.evidence == 0.0 and (est.x_m, est.y_m) == (top.x_m, top.y_m)
    assert {c.source.split(",")[0] for c in est.candidates} == {"selfcal", "onnx"}
    assert est.regions == est.components["selfcal"].regions
    assert np.hypot(*(np.array([est.x_m, est.y_m]) - tx)) < 30.0


def test_without_rounds_the_live_method_answers(repo_dir):
    """Before any round (the survey so far) the live method answers, with a note (in flight it
    costs no more than the live method); so does a log without phases."""
    log, spec, _ = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    survey = flight.select(np.asarray(flight["phase"]).astype(str) != ADAPTIVE)
    assert not survey_and_rounds(survey)[1].any()
    est = rounds_answer(survey, spec.field.origin, spec.field.rover_area)
    assert est.method == "selfcal" and "no adaptive round" in est.extras["note"]
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


@pytest.mark.parametrize(
    ("survey_s", "height", "model", "want"),
    [
        (300.0, 30.0, "rfsl_spiral_e2r_ens5.onnx", "survey"),
        (310.0, 31.0, "rfsl_spiral_e2r_ens5.onnx", "survey"),  # within 5 % and the tolerance
        (300.0, 45.0, "rfsl_spiral_alt.onnx", "given"),  # another altitude: the survey net's?
        (200.0, 30.0, "rfsl_spiral_e2r_ens5.onnx", "given"),  # another survey: another path
        (None, 30.0, "rfsl_spiral_e2r_ens5.onnx", "given"),  # no adaptive record
        (True, 30.0, "rfsl_spiral_e2r_ens5.onnx", "given"),  # a record without settings
        (300.0, 30.0, "rfsl_default.onnx", "given"),  # not a spiral: never seen by it
        (300.0, 30.0, None, "given"),
    ],
)
def test_the_survey_network_answers_only_the_survey_it_was_trained_on(
    monkeypatch, tmp_path, survey_s, height, model, want
):
    """``survey_network`` swaps a spiral network for the survey network only when the flight's
    survey is the length and the altitude the survey network was trained on."""
    net = tmp_path / ra.SURVEY_NETWORK
    net.write_bytes(b"")
    monkeypatch.setattr(
        ra, "shipped_model", lambda name: net if name == ra.SURVEY_NETWORK else None
    )
    monkeypatch.setattr(ra, "survey_domain", lambda path: (300.0, (30.0, 30.0)))
    meta = {"trajectory": {"generator": "spiral"}}
    if survey_s is not None:
        meta["trajectory"]["adaptive"] = (
            survey_s if isinstance(survey_s, bool) else {"survey_s": survey_s}
        )
    given = None if model is None else tmp_path / model
    got = ra.survey_network(meta, np.full(100, height), given)
    assert got == (net if want == "survey" else given)


def test_survey_domain_reads_the_training_mission(repo_dir):
    """The survey length comes from the training datasets' mission: a spiral network's training
    missions are fixed flights, so it has none; the survey network's is the adaptive mission's."""
    assert ra.survey_domain(repo_dir / "models" / "rfsl_spiral_e2r.onnx") is None
    net = repo_dir / "models" / ra.SURVEY_NETWORK
    if not net.exists():
        pytest.skip("no shipped survey network")
    spec = load_mission(repo_dir / ADAPTIVE_MISSION)
    assert ra.survey_domain(net) == (spec.adaptive.survey_s, (spec.altitude_m, spec.altitude_m))


def test_physics_spread_is_the_noise_where_the_physics_holds(repo_dir):
    """``physics_spread_db``: under the networks' own physics (the mission's e2r source, 1 dB
    noise) the survey departs from the prediction at the transmitter by about the noise; 80 m off
    by far more; a constant offset of the receiver changes nothing."""
    log, spec, tx = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    survey, _ = survey_and_rounds(flight)
    at_truth = ra.physics_spread_db(survey, tx, spec.source.tx_height_m)
    assert 0.6 < at_truth < 1.6  # the simulator's 1 dB noise, robustly
    assert ra.physics_spread_db(survey, tx + [80.0, 0.0], spec.source.tx_height_m) > 2 * at_truth
    shifted = survey.select(np.ones(len(survey), bool))
    shifted.columns["rss_dbm"] = np.asarray(shifted["rss_dbm"]) + 17.0
    assert ra.physics_spread_db(shifted, tx, spec.source.tx_height_m) == pytest.approx(at_truth)


@pytest.mark.parametrize("holds", [True, False])
def test_the_network_answers_where_its_physics_holds(repo_dir, monkeypatch, holds):
    """Under the gate the network's survey answer is the answer, said in a note; above it the
    rounds choose as before."""
    log, spec, _ = _flight(repo_dir, "truth")
    flight = log.flight_log(spec, spec.adaptive)
    monkeypatch.setattr(ra, "PHYSICS_SPREAD_DB", np.inf if holds else -np.inf)
    est = rounds_answer(flight, spec.field.origin, spec.field.rover_area)
    net = est.components["onnx (survey)"]
    assert est.extras["physics_spread_db"] > 0.0
    if holds:
        assert (est.x_m, est.y_m) == (net.x_m, net.y_m) and "network answers" in est.extras["note"]
        assert est.candidates[0].source == "onnx, survey, in its physics"
    else:
        assert all(c.weight is not None for c in est.candidates) and len(est.candidates) == 2
