"""A network's training altitudes, measured from its training metadata into its card, and the note
when a flight leaves them.

The note rests on a measured premise (the spiral network loses accuracy off its 30 m training
altitude), so one test re-measures it on freshly simulated spirals instead of trusting the card's
figures.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from _localize_helpers import write_synthetic_log

from mission.localize.api import localize_log
from mission.localize.onnx_model import OnnxLocalizer
from mission.localize.training_domain import ALTITUDE_TOLERANCE_M, altitude_note, flight_altitudes
from mission.workshop.dataset import DatasetConfig, dataset_heights, generate_dataset, load_dataset
from mission.workshop.domain import training_altitudes, training_domain
from mission.workshop.suite import ALTITUDE_RANGE_M


def test_shipped_networks_training_altitudes(repo_dir):
    spiral, default = (
        repo_dir / "models" / "rfsl_spiral_e2r.onnx",
        repo_dir / "models" / "rfsl_default.onnx",
    )
    if not spiral.exists() or not default.exists():
        pytest.skip("shipped models absent")
    # missions/spiral.yaml's altitude
    assert OnnxLocalizer(spiral).card.domain.altitude_m == (
        30.0,
        30.0,
    )
    # randomised 20-47 m + spiral 30 m
    assert OnnxLocalizer(default).card.domain.altitude_m == (
        20.0,
        47.0,
    )


def test_shipped_cards_hold_what_their_training_data_measures(repo_dir):
    """Each shipped card's training domain (written once by ``mission.workshop.domain``) is what its
    network's training metadata measures today: a card edited by hand, or a training record whose
    mission changed, fails."""
    models = sorted((repo_dir / "models").glob("*.onnx"))
    if not models:
        pytest.skip("shipped models absent")
    for p in models:
        net = OnnxLocalizer(p, threads=1)
        card, now = net.card.domain, training_domain(net.meta.get("training_data"))
        assert card.altitude_m == now.altitude_m, p.name
        # the simulator's attitude percentiles vary in the last bits with the libraries' thread
        # counts
        assert (card.attitude_deg is None) == (now.attitude_deg is None), p.name
        if now.attitude_deg is not None:
            assert np.asarray(card.attitude_deg) == pytest.approx(
                np.asarray(now.attitude_deg), abs=1e-9
            ), p.name
    assert net.card.domain.attitude_deg is not None  # the spiral networks know their attitude span


def test_altitudes_from_each_kind_of_dataset_record():
    def _meta(*datasets: dict) -> dict:
        return {"datasets": list(datasets)}

    assert training_altitudes(_meta({"mission_altitude_m": 45.0})) == (45.0, 45.0)
    assert training_altitudes(
        _meta(
            {"randomisation": {"altitude_m": [22.0, 33.0]}, "mission_altitude_m": 30.0},
            {"mission_altitude_m": 40.0},
        )
    ) == (22.0, 40.0)
    assert training_altitudes(_meta({"model": "suite:unseen:generic"})) == ALTITUDE_RANGE_M
    # unknown altitude anywhere: no claim at all
    assert (
        training_altitudes(_meta({"mission": "no/such/mission.yaml"}, {"mission_altitude_m": 30.0}))
        is None
    )
    assert training_altitudes({}) is None


@pytest.mark.parametrize(
    "trained, flown, says",
    [
        ((30.0, 30.0), (30.0, 30.0), None),
        ((30.0, 30.0), (25.5, 34.5), None),  # 4.5 m off: within the 5 m tolerance
        ((30.0, 30.0), (35.0, 36.0), "at 30 m; this one flew at 35-36 m, 6 m outside"),
        ((30.0, 30.0), (22.0, 24.0), "at 30 m; this one flew at 22-24 m, 8 m outside"),
        ((20.0, 47.0), (21.0, 46.0), None),  # the default's span holds every team
        ((20.0, 47.0), (55.0, 55.2), "at 20-47 m; this one flew at 55 m, 8 m outside"),
    ],
)
def test_altitude_note_cases(trained, flown, says):
    note = altitude_note("net.onnx", trained, flown)
    assert (
        note is None if says is None else note.startswith(f"net.onnx was trained on flights {says}")
    )
    assert altitude_note("net.onnx", None, flown) is None  # unknown training altitudes: no claim
    assert ALTITUDE_TOLERANCE_M == 5.0  # the cases above are written for it


def test_flight_altitudes_are_robust_percentiles():
    # ramps and a spike
    z = np.concatenate([np.full(900, 30.0), np.linspace(0, 30, 50), np.full(50, 80.0)])
    lo, hi = flight_altitudes(z)
    assert lo == pytest.approx(30.0) and hi == pytest.approx(30.0)


@pytest.mark.parametrize("alt, expect_note", [(30.0, False), (47.0, True)])
def test_localize_notes_a_flight_off_the_networks_altitude(tmp_path, repo_dir, alt, expect_note):
    model = repo_dir / "models" / "rfsl_spiral_e2r.onnx"
    if not model.exists():
        pytest.skip("shipped model absent")
    path = write_synthetic_log(tmp_path / "f.csv", alt=alt)
    est = localize_log(path, model_path=model)
    assert est.extras["network_training_altitude_m"] == [30.0, 30.0]
    assert est.extras["flight_altitude_m"] == pytest.approx([alt, alt], abs=0.5)
    assert ("was trained on flights at 30 m" in est.extras.get("note", "")) is expect_note


@pytest.mark.slow
def test_premise_spiral_network_loses_accuracy_off_its_altitude(tmp_path, repo_dir):
    """The note's premise, re-measured: 15 m above its training altitude the spiral network errs >2x
    more; the altitude-normalised network trained on 15-60 m does not."""
    model = repo_dir / "models" / "rfsl_spiral_e2r.onnx"
    if not model.exists():
        pytest.skip("shipped model absent")
    loc = OnnxLocalizer(model)
    alt_path = repo_dir / "models" / "rfsl_spiral_alt.onnx"
    alt_net = OnnxLocalizer(alt_path) if alt_path.exists() else None
    err, err_alt = {}, {}
    for alt in (30.0, 45.0):
        cfg = DatasetConfig.from_dict(
            {
                "mission": str(repo_dir / "missions" / "spiral.yaml"),
                "n": 40,
                "model": "e2r",
                "seed": 777,
                "features": ["clustering"],
            }
        )
        cfg = replace(cfg, randomisation=replace(cfg.randomisation, altitude_m=(alt, alt)))
        generate_dataset(cfg, tmp_path / f"a{alt:.0f}", workers=1)
        arrays, _ = load_dataset(tmp_path / f"a{alt:.0f}", ("clustering", "tx_enu", "params"))
        err[alt] = np.hypot(
            *(loc.predict_features(arrays["clustering"]) - arrays["tx_enu"][:, :2]).T
        ).mean()
        if alt_net is not None:
            pred = alt_net.predict_features(arrays["clustering"], dataset_heights(arrays["params"]))
            err_alt[alt] = np.hypot(*(pred - arrays["tx_enu"][:, :2]).T).mean()
    assert err[45.0] > 2.0 * err[30.0], err
    # ... and the altitude-normalised network (altitude_scale) does not: within 1.5x of its 30 m
    # error at 45 m
    if alt_net is not None:
        assert err_alt[45.0] < 1.5 * err_alt[30.0] and err_alt[45.0] < 0.5 * err[45.0], (
            err,
            err_alt,
        )
