"""The method registry (``mission.localize.methods``): every list of method names reads from it,
each factory builds a working estimator, and what an entry declares (posterior or circle, its
calibration) is what ``localize_log`` gives."""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _localize_helpers import write_synthetic_log

from mission.cli.localize import add_arguments
from mission.errors import InputError
from mission.localize.api import choose_method, localize_log, make_localizer
from mission.localize.error_circles import CIRCLE_METHODS, METHOD_CIRCLES
from mission.localize.methods import (
    CIRCLE,
    FROM_CARD,
    FROM_METHOD_CIRCLES,
    METHOD_NAMES,
    METHODS,
    POSTERIOR,
    method_entry,
    names_where,
)
from mission.workshop.evaluate import CLASSICAL, suite_method

REPO = Path(__file__).resolve().parent.parent
TX = (150.0, 120.0, 1.5)


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    return write_synthetic_log(tmp_path_factory.mktemp("logs") / "flight.csv", TX, n=3000)


def test_every_name_list_reads_from_the_registry() -> None:
    assert METHOD_NAMES == tuple(METHODS) and len(set(METHOD_NAMES)) == len(METHOD_NAMES) >= 7

    p = argparse.ArgumentParser()
    add_arguments(p)
    (act,) = [a for a in p._actions if a.dest == "method"]
    assert tuple(act.choices) == METHOD_NAMES
    # the shipped method circles are exactly the registry's circle-calibrated methods
    assert (
        CIRCLE_METHODS
        == names_where(calibration=FROM_METHOD_CIRCLES)
        == ("strongest", "centroid", "grid")
    )
    assert sorted(json.loads(METHOD_CIRCLES.read_text())) == sorted(CIRCLE_METHODS)
    assert set(CLASSICAL) <= set(METHOD_NAMES)
    for name in METHOD_NAMES:  # rfsl evaluate --suite takes every registered name
        assert suite_method(name) == {"method": name}


def test_entries_are_consistent() -> None:
    for m in METHODS.values():
        assert m.uncertainty in (POSTERIOR, CIRCLE) and m.description and m.kind
        assert (m.uncertainty == CIRCLE) == (m.calibration in (FROM_CARD, FROM_METHOD_CIRCLES)), (
            m.name
        )
        assert (
            (m.factory is None) == (m.compose is not None) == (m.kind in ("fusion", "stacking"))
        ), m.name


def test_unknown_method_names_every_known_one() -> None:
    with pytest.raises(InputError) as e:
        method_entry("kriging")
    assert all(n in str(e.value) for n in METHOD_NAMES)
    with pytest.raises(InputError, match="unknown method 'kriging'"):
        make_localizer("kriging")
    for meta in ("fusion", "evidence"):  # composed by localize_log, not one estimator
        with pytest.raises(InputError, match=meta):
            make_localizer(meta)


@pytest.mark.parametrize("name", [n for n, m in METHODS.items() if m.factory is not None])
def test_factory_builds_an_estimator(name) -> None:
    loc = make_localizer(name)
    assert callable(getattr(loc, "predict", None)), name


@pytest.mark.parametrize("name", ["strongest", "selfcal"])
def test_declared_uncertainty_is_what_localize_gives(log_path, name) -> None:
    """A circle method's regions are error circles; a posterior method's are HPD regions of its
    posterior."""
    est = localize_log(log_path, method=name)
    regions = est.to_dict()["regions"]
    assert [r["level"] for r in regions] == [0.5, 0.9]
    circles = [r.get("kind") == "error circle" for r in regions]
    if METHODS[name].uncertainty == CIRCLE:
        assert all(circles) and est.posterior is None
    else:
        assert not any(circles) and est.posterior is not None


def test_cli_help_lists_every_method_without_numpy() -> None:
    code = (
        "import argparse, sys; from mission.cli.localize import add_arguments; p = "
        "argparse.ArgumentParser(); "
        "add_arguments(p); print('numpy' in sys.modules); print(p.format_help())"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
        env={"PYTHONPATH": str(REPO), "COLUMNS": "80"},
    ).stdout
    first, _, helptext = out.partition("\n")
    assert first == "False"
    flat = re.sub(r"\s+", " ", helptext)
    assert all(n in flat for n in METHOD_NAMES)


def test_docs_describe_every_method() -> None:
    doc = (REPO / "docs" / "localize-output.md").read_text()
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `(\w+)` \| ([^|]+) \|", doc, re.M)}
    for name, m in METHODS.items():
        assert name in rows, f"docs/localize-output.md has no row for method {name}"
        assert (m.uncertainty == POSTERIOR) == ("posterior" in rows[name]), name


SPIRAL_SIM = {
    "rss_source": {
        "kind": "sim",
        "model": "e2r",
        "model_params": {"uav_pattern": "dipole", "tx_pattern": "dipole"},
    },
    "trajectory": {"generator": "spiral"},
}
LAWN_SIM = {"rss_source": {"kind": "sim", "model": "e2r"}, "trajectory": {"generator": "lawnmower"}}


@pytest.mark.parametrize(
    ("meta", "height", "model", "default", "method", "net"),
    [
        # a model given wins over everything
        ({"rss_source": {"kind": "afar-mat"}}, 30.0, "x/my.onnx", "D", "onnx", "my.onnx"),
        (SPIRAL_SIM, 30.0, "x/my.onnx", None, "onnx", "my.onnx"),
        # an adaptive flight: its answer (the live method or the survey's default, by the rounds)
        (
            {"trajectory": {"adaptive": {"rounds": 2}}, "rss_source": {"kind": "sim"}},
            30.0,
            None,
            "D",
            "rounds",
            None,
        ),
        # a real receiver (any source kind but sim, or none recorded): the real-log default
        ({"rss_source": {"kind": "afar-mat"}}, 37.0, None, "D", "fusion", None),
        ({}, 30.0, None, "D", "fusion", None),
        ({"rss_source": {"kind": "suite"}}, 30.0, None, None, "fusion", None),
        # a simulated spiral at the spiral networks' altitude: a spiral network
        (SPIRAL_SIM, 30.0, None, "D", "onnx", "rfsl_spiral_e2r_ens5.onnx"),
        # a simulated spiral far off their altitudes, or another path: the shipped default network
        (SPIRAL_SIM, 80.0, None, "D", "onnx", "D"),
        (LAWN_SIM, 30.0, None, "D", "onnx", "D"),
        # a simulated log and no default network: the grid
        (LAWN_SIM, 30.0, None, None, "grid", None),
    ],
)
def test_choose_method_table(meta, height, model, default, method, net) -> None:
    dflt = Path("models") / "D" if default == "D" else None
    got, path, why = choose_method(meta, np.full(50, height), model, dflt)
    assert got == method and why
    if net is None:
        assert path is None
    else:
        assert Path(path).name == net if net != "D" else path == dflt


@pytest.mark.parametrize(
    ("pitch", "net"),
    [((-3.0, 2.0), "rfsl_spiral_e2r_ens5.onnx"), ((-30.0, -25.0), "rfsl_spiral_tilt.onnx")],
)
def test_choose_method_hands_the_flown_attitude_to_the_simulated_default(pitch, net) -> None:
    """A simulated spiral flown nose down (PX4 SITL's -28 deg) gets the tilt network, a level one
    the ensemble: the choice reads the flight's attitude, not only its sidecar and heights."""
    if not (Path("models") / "rfsl_spiral_tilt.onnx").is_file():
        pytest.skip("no tilt network")
    got, path, why = choose_method(
        SPIRAL_SIM, np.full(50, 30.0), None, Path("models") / "D", attitude_deg=((-2.0, 3.0), pitch)
    )
    assert got == "onnx" and Path(path).name == net, why
