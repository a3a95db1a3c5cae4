"""A physics family file drives the unseen-flight benchmark (``--family F.json``)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import onnx
import pytest
from _bad_input import assert_accepted, assert_refused, run_cli, write_log
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from onnx import TensorProto, helper

from mission.cli.main import main as rfsl_main
from mission.cli.train import check_family, record_family
from mission.errors import InputError
from mission.flightlog.schema import RSS_RANGE_DB
from mission.localize.preprocess import select_samples
from mission.workshop.predictive import log_distance_residual
from mission.workshop.suite import draw_flight, family_sha256, resolve_family, unseen_flight
from mission.workshop.suite_cache import read_suite, write_suite


def _family(sigma_db: float, noise_db: float = 0.0, corr_m: float = 60.0) -> dict:
    """A family whose only randomness beyond the path is a correlated field of fixed sigma
    (isotropic free space: the log-distance fit removes the model exactly, so the residual is the
    field)."""
    return {
        "schema": 1,
        "name": f"s{sigma_db:g}",
        "spec": {
            "base": "free-space",
            "rx_pattern": "isotropic",
            "tx_pattern": "isotropic",
            "path_gain_slope": 0.0,
        },
        "residual": {"shadowing_db": sigma_db, "shadowing_corr_m": corr_m, "noise_db": noise_db},
        "offset_db": {"dist": "uniform", "lo": -5.0, "hi": 5.0},
    }


def _write(tmp_path: Path, d: dict, name: str = "fam.json") -> str:
    p = tmp_path / name
    p.write_text(json.dumps(d))
    return str(p)


def _bounds(v) -> tuple[float, float]:
    """The support of a family distribution (a number: itself)."""
    if not isinstance(v, dict):
        return float(v), float(v)
    if v["dist"] in ("uniform", "loguniform"):
        return float(v["lo"]), float(v["hi"])
    if v["dist"] == "normal":
        return float(v.get("lo", -np.inf)), float(v.get("hi", np.inf))
    vals = [float(x) for x in v["options" if v["dist"] == "choice" else "values"]]
    return min(vals), max(vals)


SHIPPED = str(Path(__file__).resolve().parents[1] / "mission" / "data" / "afar_family.json")


def test_family_draws_are_reproducible_and_seeded():
    """Same (seed, i, family) -> the same draw; another seed -> another; physics, residual, offset
    inside the shipped family's own ranges; the label naming the file's content."""
    fam = resolve_family(SHIPPED)
    a, _ = draw_flight(7, 3, SHIPPED)
    b, _ = draw_flight(7, 3, fam)
    c, _ = draw_flight(8, 3, SHIPPED)
    assert a == b and a != c
    assert a["family"] == f"json:afar@{family_sha256(fam)[:8]}" and a[
        "family_sha256"
    ] == family_sha256(fam)
    res = fam.residual
    for d in (a, c):
        for key in ("shadowing_db", "shadowing_corr_m", "noise_db"):
            lo, hi = _bounds(res[key])
            assert lo <= d[key] <= hi
        lo, hi = _bounds(fam.offset_db)
        assert lo <= d["rss_offset_db"] <= hi
        pats = {v["spec"].get("rx_pattern", fam.spec.get("rx_pattern")) for v in fam.variants} or {
            fam.spec.get("rx_pattern")
        }
        assert d["physics"]["spec"].get("rx_pattern") in pats
    # the other axes are drawn as before, before the physics
    built_in, _ = draw_flight(7, 3, "afar")
    assert (
        built_in["tx_xy"] == a["tx_xy"] and built_in["trajectory_params"] == a["trajectory_params"]
    )


@pytest.mark.slow  # three simulated flights: ~3 s on an idle core
def test_family_sigma_shows_in_the_simulated_residual(tmp_path):
    """Same seed, families differing only in shadowing sigma (2 vs 12 dB): the same field scaled, so
    the log-distance residual's spread scales by 6 and sits near the family's sigma."""
    lo = unseen_flight(11, 0, _write(tmp_path, _family(2.0), "lo.json"))
    hi = unseen_flight(11, 0, _write(tmp_path, _family(12.0), "hi.json"))
    assert lo.draw["tx_xy"] == hi.draw["tx_xy"]
    sd = []
    for f in (lo, hi):
        part, _ = select_samples(f.log)
        tx = np.array([*f.truth_xy, f.draw["tx_height_m"]])
        sd.append(float(np.std(log_distance_residual(part.enu(), part["rss_dbm"], tx))))
    assert 5.0 < sd[1] / sd[0] < 7.0
    assert 5.0 < sd[1] < 16.0
    again = unseen_flight(11, 0, _write(tmp_path, _family(12.0), "hi2.json"))
    assert np.array_equal(again.log.columns["rss_dbm"], hi.log.columns["rss_dbm"])


def test_cache_keeps_the_family_and_checks_it(tmp_path):
    """A cache drawn from a family file keeps its record: the fingerprint check re-simulates from it
    even after the file is gone, and the rewrite command names the file."""
    fam = _write(tmp_path, _family(6.0))
    write_suite(tmp_path / "s", 1, seed=5, family=fam)
    Path(fam).unlink()
    cs = read_suite(tmp_path / "s")
    assert cs.check_current() is None
    assert cs.manifest["family_sha256"] and f"--family {fam}" in cs.rewrite_command()


BAD = [
    {"schema": 2},
    {"schema": 1, "spec": {"base": "free-space"}, "residual": {"sigma": 3}},
    {
        "schema": 1,
        "spec": {"base": "free-space", "path_gain_slope": {"dist": "uniform", "lo": 2, "hi": 1}},
    },
]


@pytest.mark.parametrize(
    "argv",
    [
        ["dataset", "--n", "2", "--out", "{out}", "--family", "{fam}"],
        ["train", "{ds}", "--out", "{out}/m.onnx", "--family", "{fam}"],
        ["evaluate", "--n", "2", "--methods", "strongest", "--family", "{fam}"],
    ],
)
@pytest.mark.parametrize("bad", range(len(BAD)))
def test_bad_family_file_is_one_line_exit_2(tmp_path, capsys, argv, bad):
    fam = _write(tmp_path, BAD[bad])
    (tmp_path / "ds").mkdir()
    sub = {"{fam}": fam, "{out}": str(tmp_path / "out"), "{ds}": str(tmp_path / "ds")}
    rc, _, err = run_cli(
        rfsl_main, [sub.get(a, a.replace("{out}", sub["{out}"])) for a in argv], capsys
    )
    assert_refused(rc, err, "fam.json")


def test_missing_family_file_is_refused(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        resolve_family(str(tmp_path / "nope.json"))
    with pytest.raises(InputError, match="unknown suite family"):
        resolve_family("no-such-family")


_VALUE = st.one_of(
    st.floats(allow_nan=True),
    st.text(max_size=3),
    st.none(),
    st.fixed_dictionaries(
        {
            "dist": st.sampled_from(["uniform", "normal", "bogus"]),
            "lo": st.floats(-5, 5),
            "hi": st.floats(-5, 5),
        }
    ),
)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    key=st.sampled_from(
        ["shadowing_db", "shadowing_corr_m", "noise_db", "offset", "slope", "schema"]
    ),
    value=_VALUE,
)
def test_generated_bad_families_raise_input_error_only(tmp_path, key, value):
    """Any edit of a valid family either loads or raises InputError naming the file (never another
    exception)."""
    d = _family(4.0)
    if key == "offset":
        d["offset_db"] = value
    elif key == "slope":
        d["spec"]["path_gain_slope"] = value
    elif key == "schema":
        d["schema"] = value
    else:
        d["residual"][key] = value
    p = _write(tmp_path, d, "gen.json")
    try:
        resolve_family(p)
    except InputError as e:
        assert "gen.json" in str(e)
    else:  # accepted: then a flight draws from it, with a physical residual
        d = draw_flight(1, 0, p)[0]
        assert d["shadowing_db"] >= 0 and d["noise_db"] >= 0 and d["shadowing_corr_m"] > 0


def test_train_family_check_and_record(tmp_path):
    """rfsl train --family: a dataset drawn from another family is refused naming it; the family is
    written into the model's training_data metadata and its training report."""
    fam = _write(tmp_path, _family(5.0))
    sha = family_sha256(resolve_family(fam))
    for name, got in (("ok", sha), ("other", "0" * 64)):
        (tmp_path / name).mkdir()
        man = {"format": "rfsl-dataset/1", "physics_family": {"sha256": got}}
        (tmp_path / name / "manifest.json").write_text(json.dumps(man))
    rec = check_family(fam, [str(tmp_path / "ok")])
    assert rec["sha256"] == sha and rec["record"]["residual"]["shadowing_db"] == 5.0
    with pytest.raises(InputError, match="another family") as e:
        check_family(fam, [str(tmp_path / "ok"), str(tmp_path / "other")])
    assert "other" in str(e.value)
    graph = helper.make_graph(
        [helper.make_node("Identity", ["x"], ["y"])],
        "g",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1])],
    )
    model = helper.make_model(graph)
    model.metadata_props.add(key="training_data", value=json.dumps({"datasets": []}))
    path = tmp_path / "m.onnx"
    onnx.save(model, str(path))
    (tmp_path / "m.onnx.train.json").write_text(json.dumps({"training_data": {}}))
    record_family(path, rec)
    meta = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    assert json.loads(meta["training_data"])["physics_family"]["sha256"] == sha
    assert json.loads((tmp_path / "m.onnx.train.json").read_text())["training_data"][
        "physics_family"
    ]["label"]


@pytest.mark.slow  # two benchmark flights and two real-like logs: ~4 s
def test_evaluate_prints_predictive_checks(tmp_path, capsys):
    """rfsl evaluate --suite-dir ... --real LOGS: the checks table and verdict on stdout, the checks
    in --out."""
    fam = _write(tmp_path, _family(6.0, noise_db=1.0))
    write_suite(tmp_path / "s", 2, seed=3, family=fam)
    logs = [str(write_log(tmp_path / f"r{k}.csv", seed=k)) for k in range(2)]
    out = tmp_path / "r.json"
    rc, text, err = run_cli(
        rfsl_main,
        [
            "evaluate",
            "--suite-dir",
            tmp_path / "s",
            "--family",
            fam,
            "--methods",
            "strongest",
            "--real",
            *logs,
            "--workers",
            "1",
            "--out",
            out,
        ],
        capsys,
    )
    assert_accepted(rc, err)
    assert "posterior-predictive checks: 2 real flights vs 2 benchmark flights" in text
    rep = json.loads(out.read_text())["predictive_checks"]
    assert set(rep["checks"]) >= {"rss_spread_db", "resid_sill_db", "error m: strongest"}
    assert len(rep["benchmark_statistics"]) == 2 and rep["verdict"].startswith("the family")
    # white 1 dB noise around log distance: the real logs' residual sill is about 1 dB
    assert all(0.5 < s["resid_sill_db"] < 1.6 for s in rep["real_statistics"])


def test_the_shipped_familys_flights_read_as_plausible_logs():
    """The log schema's RSS range holds what the shipped family simulates: a simulated reading stays
    below the flight's receiver offset (flight 4 of the seed-2026 benchmark: +101.6 dB at an offset
    of +102.8, which a bound of 100 refused), and the offset 4.5 standard deviations from its mean
    (about 1 flight in 150 000 beyond) is inside the range."""
    fam = resources.files("mission").joinpath("data", "afar_family.json").read_text()
    off = json.loads(fam)["offset_db"]
    assert off["dist"] == "normal"
    lo, hi = off["mean"] - 4.5 * off["sd"], off["mean"] + 4.5 * off["sd"]
    assert RSS_RANGE_DB[0] < lo - 60.0 and hi < RSS_RANGE_DB[1]
