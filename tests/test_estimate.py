"""The typed estimate: ``regions``, ``notes`` and ``components`` are what consumers read, and
``to_dict`` (what ``--json`` prints) renders them where and how it always did."""

from __future__ import annotations

import json

import pytest
from _localize_helpers import write_synthetic_log

from mission.localize import Estimate, Fit, Selection
from mission.localize.api import localize_log
from mission.localize.error_circles import circle_regions

TX = (150.0, 120.0, 1.5)


def test_notes_render_as_one_sentence_group_where_first_added() -> None:
    est = Estimate(1.0, 2.0, "grid", extras={"a": 1})
    est.add_note(None)
    est.add_note("")
    assert est.notes == [] and "note" not in est.to_dict()
    est.add_note("first.")
    est.extras["b"] = 2
    est.add_note("second.")
    assert est.notes == ["first.", "second."]
    d = est.to_dict()
    assert d["note"] == "first. second."
    assert list(d)[-3:] == ["a", "note", "b"]  # the key stays where the first note put it
    # notes given at construction (a fusion copies its member's) are rendered in place
    copy = Estimate(0.0, 0.0, "fusion", extras=dict(est.extras), notes=list(est.notes))
    copy.add_note("third.")
    assert (
        list(copy.to_dict())[-3:] == ["a", "note", "b"]
        and copy.to_dict()["note"] == "first. second. third."
    )


@pytest.mark.parametrize("ending", ["", " ", ")", "%"])
def test_notes_read_apart_as_sentences(ending: str) -> None:
    """A note that ends without a full stop still ends its sentence before the next one (a real
    flight printed "... an extrapolation rfsl_spiral_e2r.onnx was trained ...")."""
    est = Estimate(1.0, 2.0, "fusion", notes=[f"outside the area{ending}"])
    est.add_note(f"trained at 30 m{ending}")
    assert est.notes == [f"outside the area{ending.strip()}.", f"trained at 30 m{ending.strip()}."]
    assert est.to_dict()["note"] == " ".join(est.notes)
    kept = Estimate(0.0, 0.0, "grid", notes=["asked?", "done!", "ends."])
    assert kept.notes == ["asked?", "done!", "ends."]


def test_regions_and_components_are_the_json_record() -> None:
    est = Estimate(1.0, 2.0, "fusion")
    assert est.regions == () and est.components == {}
    reg = circle_regions(1.0, 2.0, {0.5: 10.0, 0.9: 25.0}, "test")
    est.regions = list(reg)
    a, b = Estimate(0.0, 1.0, "selfcal"), Estimate(2.0, 3.0, "onnx")
    est.set_components({"selfcal": a, "net.onnx": b})
    assert est.regions == reg and est.components["net.onnx"] is b
    assert est.region(0.9) is reg[1] and est.outer_region is reg[1] and est.region(0.7) is None
    d = est.to_dict()
    assert d["regions"] == [r.to_dict() for r in reg] and d["components"] == {
        "selfcal": [0.0, 1.0],
        "net.onnx": [2.0, 3.0],
    }
    json.dumps(d)  # member estimates never leak into the JSON
    # typed regions handed over in extras (a method's constructor) become the field, in place
    made = Estimate(0.0, 0.0, "grid", extras={"a": 1, "regions": reg, "b": 2})
    assert made.regions == reg and list(made.to_dict())[-3:] == ["a", "regions", "b"]
    # a composer's own layout stays as it is: printed, not typed
    own = {"50": {"center_m": [0, 0], "semi_axes_m": [5, 5]}}
    theirs = Estimate(0.0, 0.0, "mine", extras={"regions": own})
    assert theirs.regions == () and theirs.to_dict()["regions"] is own


def test_fusion_fields_match_its_json(tmp_path, repo_dir) -> None:
    """On a real-receiver-like log the default fusion's typed fields are what --json carries."""
    net = repo_dir / "models" / "rfsl_spiral_e2r.onnx"
    if not net.exists():
        pytest.skip("no shipped network")
    log = write_synthetic_log(tmp_path / "f.csv", TX, n=3000)
    est = localize_log(log, method="fusion", model_path=net)
    d = est.to_dict()
    assert [m.method for m in est.components.values()] == ["selfcal", "onnx"]
    assert d["components"] == {n: [m.x_m, m.y_m] for n, m in est.components.items()}
    assert (est.x_m, est.y_m) == pytest.approx(
        tuple(sum((m.x_m, m.y_m)[i] for m in est.components.values()) / 2 for i in range(2))
    )
    assert d["regions"] == [r.to_dict() for r in est.regions]
    assert [r.level for r in est.regions] == [0.5, 0.9]
    assert est.regions == est.components["selfcal"].regions
    assert d.get("note") == (" ".join(est.notes) or None)


def test_selection_follows_the_method_choice_in_the_json_and_fit_reads_the_extras() -> None:
    est = Estimate(
        1.0,
        2.0,
        "selfcal",
        extras={"antenna": "dipole", "offset_db": -3.25, "residual_rms_db": 4.5},
    )
    est.extras["method_choice"] = "asked"
    est.selection = Selection(900, 1000, "mission legs")
    est.extras["log"] = "f.csv"
    keys = list(est.to_dict())
    assert keys[keys.index("method_choice") :] == [
        "method_choice",
        "cruise",
        "samples_used",
        "samples_total",
        "log",
    ]
    assert (
        est.to_dict()["samples_used"] == 900 and est.selection.line() == "900 of 1000: mission legs"
    )
    assert est.fit == Fit(-3.25, 4.5, "dipole")
    assert est.fit.line() == "offset -3.2 dB, residual rms 4.50 dB; UAV antenna: dipole"
    assert Estimate(0.0, 0.0, "onnx").fit is None
    no_choice = Estimate(0.0, 0.0, "onnx", selection=Selection(1, 2, "all"))
    assert list(no_choice.to_dict())[-3:] == ["cruise", "samples_used", "samples_total"]
