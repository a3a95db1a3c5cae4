"""The model card the runtime reads (``mission.localize.card``): the training domain written beside
a network is read back exactly, a malformed one is refused naming the card and key, and a network
without a card makes no claim."""

from __future__ import annotations

import json
import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.errors import InputError
from mission.localize.card import DOMAIN_KEY, TrainingDomain, card_path, training_domain_of
from mission.localize.error_circles import card_calibration
from mission.localize.onnx_model import OnnxLocalizer
from mission.workshop.domain import write_domain

finite = st.floats(-1e4, 1e4, allow_nan=False)
span = st.tuples(finite, finite).map(sorted).map(tuple)


@given(alt=st.none() | span, att=st.none() | st.tuples(span, span))
@settings(max_examples=100, deadline=None)
def test_a_domain_survives_its_json_record(alt, att):
    dom = TrainingDomain(alt, att)
    assert TrainingDomain.from_dict(json.loads(json.dumps(dom.to_dict())), "c.json") == dom


@given(
    key=st.sampled_from(["altitude_m", "roll_deg", "pitch_deg"]),
    bad=st.one_of(
        st.text(max_size=3),
        st.lists(finite, max_size=1),
        st.lists(finite, min_size=3, max_size=4),
        st.tuples(finite, finite).filter(lambda t: t[0] > t[1]).map(list),
        st.just({"lo": 1}),
    ),
)
@settings(max_examples=100, deadline=None)
def test_a_malformed_span_names_the_card_and_key(key, bad):
    rec = {
        "altitude_m": [20.0, 40.0],
        "roll_deg": [-5.0, 15.0],
        "pitch_deg": [-12.0, 10.0],
        key: bad,
    }
    with pytest.raises(InputError) as e:
        TrainingDomain.from_dict(rec, "net.json")
    assert str(e.value).startswith(f"net.json, field '{DOMAIN_KEY}.{key}': ")


def test_roll_and_pitch_come_together():
    with pytest.raises(InputError, match="both"):
        TrainingDomain.from_dict(
            {"altitude_m": None, "roll_deg": [0, 1], "pitch_deg": None}, "c.json"
        )


@pytest.fixture
def net(tmp_path, repo_dir):
    """A copy of the shipped spiral network and its card in a temporary folder."""
    src = repo_dir / "models" / "rfsl_spiral_e2r.onnx"
    if not src.is_file():
        pytest.skip("shipped models absent")
    shutil.copy(src, tmp_path / "net.onnx")
    shutil.copy(card_path(src), tmp_path / "net.json")
    return tmp_path / "net.onnx"


def test_the_runtime_reads_the_cards_domain_and_circles(net):
    card = OnnxLocalizer(net).card
    assert card.domain.altitude_m == (30.0, 30.0)
    # pitch down and up on the spiral
    assert card.domain.attitude_deg[1][0] < 0 < card.domain.attitude_deg[1][1]
    assert (
        card_calibration(card, "sim") == card_calibration(net, "sim")
        and card_calibration(card, "sim")[0]
    )
    doc = json.loads(card_path(net).read_text())
    doc[DOMAIN_KEY]["altitude_m"] = [25.0, 35.0]
    card_path(net).write_text(json.dumps(doc))
    # read from the card, not re-derived
    assert OnnxLocalizer(net).card.domain.altitude_m == (
        25.0,
        35.0,
    )
    doc[DOMAIN_KEY]["pitch_deg"] = [3.0]
    card_path(net).write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        OnnxLocalizer(net)
    assert (e.value.source, e.value.field) == (str(card_path(net)), f"{DOMAIN_KEY}.pitch_deg")


def test_the_routers_read_the_same_domain_without_a_session(net):
    """``training_domain_of`` (what the routers read) is the runtime card's domain, from the JSON
    card alone: the same spans, the same refusal of a malformed one, no claim without a card."""
    assert training_domain_of(net) == OnnxLocalizer(net).card.domain != TrainingDomain()
    doc = json.loads(card_path(net).read_text())
    doc[DOMAIN_KEY]["altitude_m"] = [25.0, 35.0]
    card_path(net).write_text(json.dumps(doc))
    assert training_domain_of(net).altitude_m == (25.0, 35.0)
    doc[DOMAIN_KEY]["pitch_deg"] = [3.0]
    card_path(net).write_text(json.dumps(doc))
    with pytest.raises(InputError, match="pitch_deg"):
        training_domain_of(net)
    card_path(net).unlink()
    assert training_domain_of(net) == TrainingDomain()


def test_a_network_without_a_card_makes_no_claim(net):
    card_path(net).unlink()
    card = OnnxLocalizer(net).card
    assert card.domain == TrainingDomain() and card.regions is None
    assert card_calibration(card, "real") == (
        None,
        "net.onnx has no model card (net.json, benchmarks/calibrate_error_circles.py)",
    )


def test_write_domain_adds_the_domain_and_keeps_the_rest(net):
    before = json.loads(card_path(net).read_text())
    dom = write_domain(net, {"datasets": [{"randomisation": {"altitude_m": [22.0, 33.0]}}]})
    after = json.loads(card_path(net).read_text())
    assert dom == TrainingDomain((22.0, 33.0), None) and after[DOMAIN_KEY] == dom.to_dict()
    assert {k: v for k, v in after.items() if k != DOMAIN_KEY} == {
        k: v for k, v in before.items() if k != DOMAIN_KEY
    }
    assert OnnxLocalizer(net).card.domain == dom
    card_path(net).unlink()
    write_domain(net, None)  # no card yet: one is made, with no claim
    assert json.loads(card_path(net).read_text()) == {
        "model": "net.onnx",
        DOMAIN_KEY: TrainingDomain().to_dict(),
    }
