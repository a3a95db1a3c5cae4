"""``localize`` CLI and ONNX inference: errors as one line + exit 2, JSON schema, a hand-built ONNX
model."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _figures import assert_png_drawn, capture_figures, legend_labels
from _localize_helpers import write_synthetic_log
from onnx import TensorProto, helper, numpy_helper

from mission.cli.localize import main as localize
from mission.errors import InputError
from mission.flightlog import read_flight_log
from mission.geo import afar_field
from mission.localize.api import localize_log
from mission.localize.features import FeatureConfig, cluster_features
from mission.localize.onnx_model import OnnxLocalizer
from mission.localize.preprocess import select_cruise

TX = (150.0, 120.0, 1.5)


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    return write_synthetic_log(tmp_path_factory.mktemp("logs") / "flight.csv", TX)


def one_error_line(capsys, *needles):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:"), err
    for n in needles:
        assert n in err[0], err[0]
    return err[0]


@pytest.mark.parametrize("method", ["strongest", "centroid"])
def test_json_schema(log_path, capsys, method):
    assert localize([str(log_path), "--method", method, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    for k in ("lat_deg", "lon_deg", "x_m", "y_m", "method", "model", "error_m"):
        assert k in d
    assert d["method"] == method and d["error_m"] < 15.0
    lat, lon, _ = afar_field().origin.to_geodetic(np.array([d["x_m"], d["y_m"], 0.0]))
    assert (d["lat_deg"], d["lon_deg"]) == pytest.approx((float(lat), float(lon)))


def test_default_method_and_plot(log_path, tmp_path, capsys):
    pytest.importorskip("mission.physics")
    png = tmp_path / "p.png"
    with capture_figures() as figs:
        assert localize([str(log_path), "--json", "--plot", str(png)]) == 0
    d = json.loads(capsys.readouterr().out)
    # a simulated log (sidecar rss_source kind "sim") without a trajectory: the simulated-log route,
    # rfsl_default
    assert (d["method"], d["model"]) == ("onnx", "rfsl_default.onnx") and "no trajectory" in d[
        "method_choice"
    ]
    assert_png_drawn(png, size=(1020, 900))  # 8.5 x 7.5 in at 120 dpi
    (fig,) = figs
    ax = fig.axes[0]  # the map (then its colour bar)
    labels = legend_labels(ax)
    assert labels[-1] == "truth" and any(lb.startswith(f"estimate ({d['method']}") for lb in labels)
    star = [ln for ln in ax.lines if ln.get_label().startswith("estimate")][0]
    truth = [ln for ln in ax.lines if ln.get_label() == "truth"][0]
    assert (star.get_xdata()[0], star.get_ydata()[0]) == pytest.approx(
        (d["x_m"], d["y_m"]), abs=0.01
    )
    assert (truth.get_xdata()[0], truth.get_ydata()[0]) == pytest.approx(TX[:2], abs=0.01)
    assert f"error {d['error_m']:.1f} m" in ax.get_title()


def _rewrite(src, dst, edit):
    lines = src.read_text().splitlines()
    lines = edit(lines)
    dst.write_text("\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize(
    "edit,needles",
    [
        (lambda ls: ls[:5] + [ls[5].replace(",", ";", 1)] + ls[6:], ["row 6"]),
        (
            lambda ls: ls[:7] + [",".join(ls[7].split(",")[:-1] + ["nan"])] + ls[8:],
            ["row 8", "rss_dbm"],
        ),
        (lambda ls: [ls[0].replace(",rss_dbm", ",power")] + ls[1:], ["rss_dbm"]),
        (lambda ls: ls[:10] + [ls[8]] + ls[11:], ["row 11", "t_s"]),
        (lambda ls: ls[:4] + [ls[4].replace("35.7", "3570.", 1)] + ls[5:], ["row 5", "lat_deg"]),
    ],
)
def test_bad_logs_exit_2(log_path, tmp_path, capsys, edit, needles):
    bad = _rewrite(log_path, tmp_path / "bad.csv", edit)
    assert localize([str(bad), "--method", "strongest"]) == 2
    one_error_line(capsys, "bad.csv", *needles)


def test_missing_file(tmp_path, capsys):
    assert localize([str(tmp_path / "none.csv")]) == 2
    one_error_line(capsys, "none.csv")


def make_onnx(
    path,
    cfg: FeatureConfig,
    w: np.ndarray,
    b: np.ndarray,
    norm: dict,
    kind="clustering",
    drop_key=None,
    width=None,
):
    onnx = pytest.importorskip("onnx")

    f = width or w.shape[0]
    g = helper.make_graph(
        [
            helper.make_node("MatMul", ["x", "W"], ["h"]),
            helper.make_node("Add", ["h", "b"], ["xy"]),
        ],
        "lin",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", f])],
        [helper.make_tensor_value_info("xy", TensorProto.FLOAT, ["batch", 2])],
        [
            numpy_helper.from_array(w.astype(np.float32), "W"),
            numpy_helper.from_array(b.astype(np.float32), "b"),
        ],
    )
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 9
    props = {
        "feature_kind": json.dumps(kind),
        "feature_config": json.dumps(cfg.to_dict()),
        "input_normalisation": json.dumps(norm),
        "field_origin": json.dumps(afar_field().origin.to_dict()),
        "training_data": json.dumps({"note": "hand-built test model"}),
    }
    if drop_key:
        props.pop(drop_key)
    helper.set_model_props(m, props)
    onnx.save(m, str(path))
    return path


def test_onnx_end_to_end(log_path, tmp_path, capsys):
    cfg = FeatureConfig()
    f = cfg.n_features
    w = np.zeros((f, 2))
    w[1, 0] = w[2, 1] = 1.0  # output = (x_1, y_1) of the strongest cluster, normalised
    mean, std = np.full(f, 5.0), np.full(f, 2.0)
    norm = {
        "input_mean": mean.tolist(),
        "input_std": std.tolist(),
        "output_mean": [4.0, 4.5],
        "output_std": [2.0, 2.0],
    }
    path = make_onnx(tmp_path / "m.onnx", cfg, w, np.array([0.5, 0.25]), norm)
    loc = OnnxLocalizer(path, expect_config=cfg, expect_kind="clustering")
    part, _ = select_cruise(read_flight_log(log_path))
    enu = part.enu()
    v = cluster_features(enu[:, 0], enu[:, 1], part["rss_dbm"], cfg)
    expect = (((v - mean) / std) @ w + [0.5, 0.25]) * 2.0 + [4.0, 4.5]  # = (x_1, y_1) exactly
    np.testing.assert_allclose(expect, v[1:3], atol=1e-9)
    e = loc.predict(part)
    np.testing.assert_allclose([e.x_m, e.y_m], expect, atol=1e-3)
    e2 = localize_log(log_path, model_path=path)
    assert e2.method == "onnx" and e2.model == "m.onnx"
    np.testing.assert_allclose([e2.x_m, e2.y_m], expect, atol=1e-3)
    assert localize([str(log_path), "--model", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["method"] == "onnx" and d["model"] == "m.onnx" and d["error_m"] < 20.0


def test_onnx_refusals(log_path, tmp_path, capsys):
    cfg = FeatureConfig()
    f = cfg.n_features
    norm = {"input_mean": 0.0, "input_std": 1.0, "output_mean": [0, 0], "output_std": [1, 1]}
    good = make_onnx(tmp_path / "g.onnx", cfg, np.zeros((f, 2)), np.zeros(2), norm)
    with pytest.raises(InputError, match="feature_config.n_t"):
        OnnxLocalizer(good, expect_config=FeatureConfig(n_t=30))
    with pytest.raises(InputError, match="feature_kind"):
        OnnxLocalizer(good, expect_kind="normalised_rss")
    nocfg = make_onnx(
        tmp_path / "n.onnx", cfg, np.zeros((f, 2)), np.zeros(2), norm, drop_key="feature_config"
    )
    with pytest.raises(InputError, match="feature_config"):
        OnnxLocalizer(nocfg)
    # a model whose feature configuration does not match its own network / this software: CLI exit 2
    wrong = make_onnx(
        tmp_path / "w.onnx", FeatureConfig(c_k=10), np.zeros((f, 2)), np.zeros(2), norm
    )
    assert localize([str(log_path), "--model", str(wrong)]) == 2
    one_error_line(capsys, "w.onnx", "feature_config.c_k")
    old = FeatureConfig(version=99)
    ver = make_onnx(tmp_path / "v.onnx", old, np.zeros((f, 2)), np.zeros(2), norm)
    assert localize([str(log_path), "--model", str(ver), "--json"]) == 2
    one_error_line(capsys, "v.onnx", "feature_config.version")
    junk = tmp_path / "j.onnx"
    junk.write_bytes(b"junk")
    assert localize([str(log_path), "--model", str(junk)]) == 2
    one_error_line(capsys, "j.onnx")


def test_estimate_far_outside_the_rover_area_is_flagged(log_path, tmp_path, capsys):
    """A network is not bounded to the field: an estimate far outside the rover area is reported
    with a warning (JSON field and table row), never silently; one inside gets none."""
    cfg = FeatureConfig()
    f = cfg.n_features
    far = {
        "input_mean": 0.0,
        "input_std": 1.0,
        "output_mean": [900.0, -700.0],
        "output_std": [1, 1],
    }
    path = make_onnx(tmp_path / "far.onnx", cfg, np.zeros((f, 2)), np.zeros(2), far)
    assert localize([str(log_path), "--model", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["x_m"] > 800 and "outside the rover area" in d["warning"]
    assert localize([str(log_path), "--model", str(path)]) == 0
    assert "warning" in capsys.readouterr().out
    assert localize([str(log_path), "--method", "strongest", "--json"]) == 0
    assert "warning" not in json.loads(capsys.readouterr().out)


def test_fusion_takes_another_network(log_path, repo_dir, capsys):
    """--method fusion --model X fuses the self-calibrating estimate with network X (the mean of the
    two); --model with a method that has no network is refused with one line."""
    net = repo_dir / "models" / "rfsl_spiral_e2r_ens5.onnx"
    if not net.exists():
        pytest.skip("no shipped ensemble")
    assert localize([str(log_path), "--method", "fusion", "--model", str(net), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["method"] == "fusion" and set(d["components"]) == {"selfcal", net.name}
    mean = np.mean(list(d["components"].values()), axis=0)
    assert (d["x_m"], d["y_m"]) == pytest.approx(tuple(mean))
    assert localize([str(log_path), "--method", "selfcal", "--model", str(net)]) == 2
    one_error_line(capsys, "--model needs --method onnx or fusion")
