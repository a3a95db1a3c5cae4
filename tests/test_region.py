"""The typed region (``mission.localize.region``): its JSON is the historic layout key for key, it
reads an old ``--json`` back, refuses a bad one in one line, and reads the same in every output."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.errors import InputError
from mission.geo import Area
from mission.localize.error_circles import circle_regions
from mission.localize.region import CIRCLE, HPD, Ellipse, Region
from mission.localize.uncertainty import Posterior, hpd_regions

HPD_KEYS = ["level", "hpd_mass", "area_m2", "density", "ellipse", "polygons"]
CIRCLE_KEYS = [
    "level",
    "hpd_mass",
    "kind",
    "radius_m",
    "area_m2",
    "ellipse",
    "polygons",
    "calibrated_on",
]


def _gaussian_regions() -> tuple[Region, ...]:
    gx, gy = np.meshgrid(np.arange(-100.0, 101.0, 4.0), np.arange(-80.0, 81.0, 4.0))
    p = np.exp(-0.5 * ((gx - 10.0) ** 2 / 30.0**2 + (gy + 5.0) ** 2 / 15.0**2))
    post = Posterior(p / p.sum(), None)  # type: ignore[arg-type]
    return hpd_regions(post, np.stack([gx, gy], axis=-1), (0.5, 0.9), {0.9: 0.93})


SQUARE = Area("rover area", np.array([[-50.0, -50.0], [30.0, -50.0], [30.0, 50.0], [-50.0, 50.0]]))


def _all_kinds() -> list[Region]:
    return [
        *_gaussian_regions(),
        *circle_regions(0.0, 0.0, {0.5: 12.0, 0.9: 40.0}, "real; 200 flights", SQUARE),
    ]


def test_json_is_the_historic_layout_and_reads_back() -> None:
    hpd50, hpd90, circ50, circ90 = _all_kinds()
    assert hpd90.kind == HPD and hpd90.mass == 0.93 and hpd50.mass == 0.5
    assert list(hpd90.to_dict()) == HPD_KEYS and list(hpd90.to_dict()["ellipse"]) == [
        "x_m",
        "y_m",
        "a_m",
        "b_m",
        "angle_deg",
    ]
    # inside the square: whole; across its east edge: clipped (the key last)
    assert circ50.clipped_to is None and list(circ50.to_dict()) == CIRCLE_KEYS
    assert circ90.kind == CIRCLE and list(circ90.to_dict()) == [*CIRCLE_KEYS, "clipped_to"]
    assert circ90.area_m2 < math.pi * 40.0**2 and circ90.ellipse.a_m == circ90.radius_m == 40.0
    for reg in (hpd50, hpd90, circ50, circ90):
        d = json.loads(json.dumps(reg.to_dict()))  # what --json wrote, read back
        assert Region.from_dict(d) == reg and Region.from_dict(d).to_dict() == reg.to_dict()


def _corrupt(draw_kind: int, what: int, bad) -> tuple[dict, str]:
    """A valid region's JSON with one field made bad: (the dict, the field to be named)."""
    d = _all_kinds()[draw_kind].to_dict()
    keys = [k for k in d if k != "kind"]
    k = keys[what % len(keys)]
    if bad == "drop":
        del d[k]
    elif bad == "unknown":
        d["lev"] = 0.5
        k = "lev"
    elif k == "ellipse":
        sub = ["x_m", "y_m", "a_m", "b_m", "angle_deg"][what % 5]
        finite = isinstance(bad, float) and math.isfinite(bad)  # any finite number is valid here
        d["ellipse"][sub] = None if finite or isinstance(bad, str) else bad
        k = f"ellipse.{sub}"
    elif k in ("calibrated_on", "clipped_to"):
        d[k] = 3.0
    else:
        d[k] = bad
    return d, k


@given(
    kind=st.integers(0, 3),
    what=st.integers(0, 20),
    bad=st.one_of(
        st.sampled_from(["drop", "unknown", "x", True, [], {}]),
        st.sampled_from([math.nan, math.inf, -math.inf, -1.0, "12"]),
    ),
)
@settings(max_examples=150, deadline=None)
def test_a_bad_field_is_one_line_naming_it(kind, what, bad) -> None:
    d, field = _corrupt(kind, what, bad)
    if field == "polygons" and bad == []:
        assert Region.from_dict(d).polygons == ()  # no outline is a valid region
        return
    if field == "clipped_to" and bad == "drop":
        assert Region.from_dict(d).clipped_to is None  # a circle not clipped
        return
    with pytest.raises(InputError) as e:
        Region.from_dict(d, source="old.json", key="regions[1]")
    msg = str(e.value)
    assert "\n" not in msg and "old.json" in msg and f"regions[1].{field}" in msg, msg


@given(st.one_of(st.none(), st.integers(), st.text(max_size=5), st.lists(st.floats(), max_size=2)))
@settings(max_examples=40, deadline=None)
def test_not_a_mapping_is_refused_in_one_line(value) -> None:
    with pytest.raises(InputError) as e:
        Region.from_dict(value if value is not None else [], source="old.json")
    assert "\n" not in str(e.value) and "old.json" in str(e.value)
    d = _all_kinds()[0].to_dict()
    with pytest.raises(InputError, match="kind"):
        Region.from_dict(dict(d, kind="square"), source="old.json")


def test_a_region_reads_the_same_everywhere() -> None:
    hpd = Region(0.9, 0.93, 5432.1, Ellipse(12.34, -5.67, 60.4, 30.6, 17.0), (), density=1.2e-4)
    assert hpd.describe() == (
        "5432 m^2; ellipse centre 12.3, -5.7 m, semi-axes 60 x 31 m at 17 deg from east"
    )
    assert hpd.describe(short=True) == "5432 m^2 (ellipse 60 x 31 m)"
    circ = Region(
        0.9,
        0.9,
        3000.0,
        Ellipse(0.0, 0.0, 40.0, 40.0, 0.0),
        kind=CIRCLE,
        radius_m=40.0,
        calibrated_on="real",
        clipped_to="rover area",
    )
    assert circ.describe(short=True) == "within 40 m of the estimate"
    assert circ.describe() == (
        "within 40 m of the estimate (error circle; calibrated on real; clipped to the rover "
        "area: 3000 m^2)"
    )
    with pytest.raises(ValueError):
        Region(0.5, 0.5, 1.0, circ.ellipse, kind=CIRCLE)  # a circle needs its radius
    with pytest.raises(ValueError):
        Region(0.5, 0.5, 1.0, circ.ellipse, kind="square")


@given(
    a=st.floats(1.0, 500.0),
    ratio=st.floats(0.05, 1.0),
    ang=st.floats(-180.0, 180.0),
    t=st.floats(0.0, 2 * math.pi),
)
@settings(max_examples=80, deadline=None)
def test_the_ellipse_holds_its_rim_from_inside_only(a, ratio, ang, t) -> None:
    """A point at 0.99 of the rim in any direction (the ellipse's own parametrisation, rotated by
    its angle) is inside, at 1.01 outside."""
    b = a * ratio
    el = Ellipse(30.0, -20.0, a, b, ang)
    c, s = math.cos(math.radians(ang)), math.sin(math.radians(ang))
    u, v = a * math.cos(t), b * math.sin(t)
    rim = np.array([u * c - v * s, u * s + v * c])
    assert el.contains(*(np.array([30.0, -20.0]) + 0.99 * rim))
    assert not el.contains(*(np.array([30.0, -20.0]) + 1.01 * rim))
