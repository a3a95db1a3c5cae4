"""Strict JSON (``mission.jsonsafe``): what ``rfsl gap`` writes must load in strict readers (no
NaN/Infinity)."""

from __future__ import annotations

import json
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mission import jsonsafe


def strict_loads(text: str):
    """``json.loads`` that refuses NaN / Infinity / -Infinity, as strict JSON readers do."""

    def refuse(name: str):
        raise ValueError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


leaf = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.text(max_size=5),
    st.none(),
    st.booleans(),
)
tree = st.recursive(
    leaf,
    lambda c: st.one_of(
        st.lists(c, max_size=4), st.dictionaries(st.text(max_size=4), c, max_size=4)
    ),
    max_leaves=20,
)


@settings(max_examples=80, deadline=None)
@given(tree)
def test_any_nested_value_becomes_strict_json_with_finite_numbers_kept(o):
    back = strict_loads(jsonsafe.dumps(o))

    def same(a, b):
        if isinstance(a, float) and not math.isfinite(a):
            return b is None
        if isinstance(a, dict):
            return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
        if isinstance(a, list):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
        return a == b

    assert same(o, back)


def test_numpy_values():
    doc = {
        "a": np.array([1.0, np.inf, np.nan]),
        "b": np.float32(2.5),
        "c": np.int64(3),
        "d": np.float64(-np.inf),
    }
    assert strict_loads(jsonsafe.dumps(doc)) == {
        "a": [1.0, None, None],
        "b": 2.5,
        "c": 3,
        "d": None,
    }
