"""The one validation layer (``mission.fields``): every accessor either returns the value in its
type or refuses it with a one-line ``InputError`` naming the file and the dotted field; the
validators built on it (a physics family's distributions, a sidecar's types, a dataset
configuration) refuse generated bad values the same way and never raise anything else."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.errors import InputError, one_line
from mission.fields import REQUIRED, Fields, check_types
from mission.localize.altitude_scale import METADATA_KEY, reference_height
from mission.physics.family import check_dist
from mission.workshop.dataset_config import DatasetConfig, Randomisation, check_config
from mission.workshop.suite_cache import FORMAT as SUITE_FORMAT
from mission.workshop.suite_cache import CachedSuite

SRC = "cfg.yaml"
# any JSON-ish value a user's file can hold
VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**6), 10**6)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=4),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=3), inner, max_size=3)
    ),
    max_leaves=6,
)


def _refused(e: InputError, field: str) -> None:
    msg = str(e)
    assert len(msg.splitlines()) == 1 and msg.startswith(one_line(f"{SRC}, field '{field}': ")), msg
    assert e.exit_code == 2 and e.field == field


def _is_num(v) -> bool:  # written out here: the test does not take the layer's word for it
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


@settings(max_examples=150, deadline=None)
@given(v=VALUES, lo=st.none() | st.floats(-10, 10), hi=st.none() | st.floats(-10, 10))
def test_num_takes_finite_numbers_in_range_and_names_the_field_otherwise(v, lo, hi):
    f = Fields({"a": {"b": v}}, SRC).sub("a")
    ok = _is_num(v) and (lo is None or v >= lo) and (hi is None or v <= hi)
    if ok:
        assert f.num("b", lo=lo, hi=hi) == float(v)
    else:
        with pytest.raises(InputError) as e:
            f.num("b", lo=lo, hi=hi)
        _refused(e.value, "a.b")


@settings(max_examples=150, deadline=None)
@given(v=VALUES)
def test_each_accessor_returns_its_type_or_refuses(v):
    f = Fields({"k": v}, SRC, "top")
    cases = [
        (f.int_, lambda x: isinstance(x, int) and not isinstance(x, bool)),
        (f.str_, lambda x: isinstance(x, str)),
        (f.bool_, lambda x: isinstance(x, bool)),
        (
            f.span,
            lambda x: isinstance(x, list) and len(x) == 2 and all(map(_is_num, x)) and x[0] <= x[1],
        ),
    ]
    for read, accepts in cases:
        if accepts(v):
            got = read("k")
            assert got == (tuple(float(x) for x in v) if read == f.span else v)
        else:
            with pytest.raises(InputError) as e:
                read("k")
            _refused(e.value, "top.k")


@settings(max_examples=100, deadline=None)
@given(v=VALUES)
def test_optional_and_required_keys(v):
    f = Fields({}, SRC)
    assert f.num("x", None) is None and f.str_("y", None) is None and f.span("z", None) is None
    with pytest.raises(InputError) as e:
        f.num("x", REQUIRED)
    _refused(e.value, "x")
    if not isinstance(v, dict) and v is not None:
        with pytest.raises(InputError) as e:
            Fields({"m": v}, SRC).sub("m")
        _refused(e.value, "m")


@given(keys=st.lists(st.text(min_size=1, max_size=4), min_size=1, max_size=4, unique=True))
@settings(max_examples=100, deadline=None)
def test_done_refuses_the_first_unread_key(keys):
    f = Fields(dict.fromkeys(keys, 1), SRC, "blk")
    f.raw(keys[0])
    if len(keys) == 1:
        f.done()
        return
    with pytest.raises(InputError) as e:
        f.done()
    _refused(e.value, f"blk.{keys[1]}")


@settings(max_examples=150, deadline=None)
@given(v=VALUES)
def test_typed_checks_the_json_type(v):
    d = {"rss_source": {"seed": v}}
    ok = v is None or (isinstance(v, int) and not isinstance(v, bool))
    if ok:
        check_types(d, {"rss_source.seed": (int,)}, SRC)
    else:
        with pytest.raises(InputError) as e:
            check_types(d, {"rss_source.seed": (int,)}, SRC)
        _refused(e.value, "rss_source.seed")


DISTS = st.fixed_dictionaries(
    {"dist": st.sampled_from(["uniform", "loguniform", "normal", "choice", "empirical", "x"])},
    optional={
        k: VALUES | st.floats(-5, 5) for k in ("lo", "hi", "mean", "sd", "options", "values", "p")
    },
)


@settings(max_examples=150, deadline=None)
@given(v=DISTS | VALUES)
def test_a_generated_distribution_is_accepted_or_refused_naming_its_field(v):
    """Any value where a family holds a distribution: accepted, or one InputError naming a field
    under ``spec.beta`` (a text ``lo`` was a ValueError before)."""
    try:
        check_dist(v, "spec.beta", SRC)
    except InputError as e:
        assert (
            len(str(e).splitlines()) == 1 and e.source == SRC and e.field.startswith("spec.beta")
        ), str(e)


@settings(max_examples=100, deadline=None)
@given(
    fixed=st.none() | st.floats(-1, 2),
    speed=st.none() | st.tuples(st.floats(-2, 5), st.floats(-2, 5)),
)
def test_dataset_config_names_the_randomisation_field(fixed, speed):
    cfg = DatasetConfig(None, 4, randomisation=Randomisation(fixed_heading=fixed, speed_mps=speed))
    bad = {
        "fixed_heading": fixed is not None and not 0 <= fixed <= 1,
        "speed_mps": speed is not None and min(speed) <= 0,
    }
    if not any(bad.values()):
        check_config(cfg)
        return
    with pytest.raises(InputError) as e:
        check_config(cfg)
    assert e.value.field == next(k for k, b in bad.items() if b)
    assert len(str(e.value).splitlines()) == 1


@settings(max_examples=100, deadline=None)
@given(v=VALUES)
def test_a_cards_reference_height_is_a_positive_number_or_refused(v):
    """The model card's altitude-normalisation entry (``altitude_scale.reference_height``)."""
    td = {METADATA_KEY: {"reference_height_m": v}}
    if _is_num(v) and v > 0:
        assert reference_height(td, SRC) == float(v)
        return
    with pytest.raises(InputError) as e:
        reference_height(td, SRC)
    _refused(e.value, f"training_data.{METADATA_KEY}.reference_height_m")
    assert reference_height({}, SRC) is None and reference_height(None, SRC) is None


@settings(max_examples=100, deadline=None)
@given(key=st.sampled_from(["format", "flights", "file", "truth_xy", "draw"]), v=VALUES)
def test_a_suite_manifest_is_read_or_refused_naming_the_field(tmp_path_factory, key, v):
    """``suite.json`` with one value replaced: read, or one InputError naming the file (a text
    ``truth_xy`` or a missing ``flights`` was a traceback)."""
    flight = {"file": "f.csv", "truth_xy": [1.0, 2.0], "draw": {}}
    m = {"format": SUITE_FORMAT, "flights": [flight]}
    if key in ("format", "flights"):
        m[key] = v
    else:
        flight[key] = v
    d = tmp_path_factory.mktemp("suite")
    (d / "suite.json").write_text(json.dumps(m))
    try:
        cs = CachedSuite(d)
    except InputError as e:
        assert len(str(e).splitlines()) == 1 and e.source == str(d / "suite.json"), str(e)
    else:
        assert cs.manifest == m and len(cs) == len(m["flights"])
