"""One renderer (``mission.localize.render.Shown``) for the ``localize`` table, ``fly-mission``'s
last lines and the live status line: the same facts in the same words, each line within 80
columns."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from mission.flight.live import LEVEL, summary
from mission.localize import Estimate
from mission.localize.error_circles import circle_regions
from mission.localize.region import Ellipse, Region
from mission.localize.render import NO_REGION, Shown

TRUTH = {"x_m": 225.8, "y_m": 254.2}


def _network_estimate() -> Estimate:
    est = Estimate(
        225.7,
        254.7,
        "onnx",
        "rfsl_spiral_e2r_ens5.onnx",
        35.7291773,
        -78.697044,
        extras={"model_path": "/x/models/rfsl_spiral_e2r_ens5.onnx"},
    )
    est.regions = circle_regions(est.x_m, est.y_m, {0.5: 4.2, 0.9: 10.1}, "sim spirals")
    return est


def test_last_lines_of_a_flight() -> None:
    """The README's example, from the estimate and the truth the flight knows."""
    assert Shown.of(_network_estimate(), TRUTH).lines() == [
        "estimate: x=225.7 m, y=254.7 m (lat 35.7291773, lon -78.6970440)",
        "  method: onnx rfsl_spiral_e2r_ens5.onnx",
        "  90 % region: within 10 m of the estimate",
        "  error: 0.5 m (true transmitter at 225.8, 254.2 m)",
    ]
    bare = Estimate(1.0, 2.0, "grid", None, 35.0, -78.0)
    assert Shown.of(bare).lines()[1:] == ["  method: grid", f"  region: {NO_REGION}"]


def test_the_table_and_the_last_lines_say_the_error_alike() -> None:
    """``localize`` reads the truth from the sidecar (``error_m``, ``truth_x_m``): its error row
    is the last lines' error, bold; its region rows give every region in full."""
    est = _network_estimate()
    est.error_m = math.hypot(est.x_m - TRUTH["x_m"], est.y_m - TRUTH["y_m"])
    est.extras.update(truth_x_m=TRUTH["x_m"], truth_y_m=TRUTH["y_m"])
    rows = dict(Shown.of(est).rows())
    assert rows == {
        "local x, y": "225.7 m east, 254.7 m north (log origin)",
        "lat, lon": "35.7291773, -78.6970440",
        "error": "[bold]0.5 m[/] (true transmitter at 225.8, 254.2 m)",
    }
    assert Shown.of(est).lines()[-1] == "  error: " + rows["error"].replace("[bold]", "").replace(
        "[/]", ""
    )
    assert [k for k, _ in Shown.of(est).region_rows()] == ["50 % region", "90 % region"]
    assert (
        Shown.of(est)
        .region_rows()[1][1]
        .startswith("within 10 m of the estimate (error circle; calibrated on sim spirals")
    )
    assert "error" not in dict(Shown.of(Estimate(0.0, 0.0, "grid")).rows())


def test_the_status_line_reads_the_same_from_the_estimate_and_its_series_entry() -> None:
    """What the flight shows while it flies (the series entry the sidecar keeps) and the estimate
    it came from render alike; the in-flight last lines say when, and how to get it back."""
    est = _network_estimate()
    d = summary(est, 312.5)
    assert d["area_m2"] == round(est.region(LEVEL).area_m2, 1)
    line = Shown.of_entry(d, TRUTH).line()
    assert line == Shown.of(est, TRUTH).line() == "(226, 255) m, 90 % in 320 m^2, error 0.5 m"
    assert Shown.of_entry(d, TRUTH, "selfcal").lines() == [
        "estimate: x=225.7 m, y=254.7 m",
        "  method: onnx, in flight at t=312.5 s",
        "  (`localize LOG --at 312.5` gives it back)",
        "  90 % region: 320 m^2",
        "  error: 0.5 m (true transmitter at 225.8, 254.2 m)",
    ]
    no_method = {k: v for k, v in d.items() if k not in ("method", "area_m2")}
    shown = Shown.of_entry(no_method, None, "selfcal")
    assert shown.line() == "(226, 255) m" and shown.lines()[1].startswith("  method: selfcal,")
    assert shown.lines()[-1] == f"  region: {NO_REGION}"


XY = st.floats(-9999.0, 9999.0)


@given(
    x=XY,
    y=XY,
    tx=XY,
    ty=XY,
    lat=st.floats(-89.9, 89.9),
    lon=st.floats(-179.9, 179.9),
    area=st.floats(1.0, 9.9e7),
    axes=st.tuples(st.floats(0.0, 9999.0), st.floats(0.0, 9999.0)),
    radius=st.floats(0.5, 9999.0),
    t=st.floats(0.0, 99999.0),
)
@settings(max_examples=80, deadline=None)
def test_every_line_fits_80_columns(x, y, tx, ty, lat, lon, area, axes, radius, t) -> None:
    truth = {"x_m": tx, "y_m": ty}
    hpd = Region(0.9, 0.93, area, Ellipse(x, y, max(axes), min(axes), 10.0), density=1e-4)
    circle = circle_regions(x, y, {0.9: radius}, "real")[0]
    for reg in (hpd, circle):
        est = Estimate(x, y, "evidence", None, lat, lon)
        est.regions = [reg]
        entry = summary(est, t)
        for shown in (Shown.of(est, truth), Shown.of_entry(entry, truth)):
            lines = [*shown.lines(), shown.line()]
            assert max(map(len, lines)) <= 80, lines
