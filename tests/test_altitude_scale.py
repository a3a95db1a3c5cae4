"""Altitude-normalised network coordinates: the physics premise (closed form), the scaling helpers,
and the wiring from a log's heights to the network (training flag, metadata, inference)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from _localize_helpers import write_synthetic_log
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.cli.localize import main
from mission.errors import InputError
from mission.flightlog import read_flight_log
from mission.localize.altitude_scale import (
    MIN_HEIGHT_M,
    REFERENCE_HEIGHT_M,
    flight_height,
    scale_cluster_xy,
    scale_factor,
)
from mission.localize.api import localize_log
from mission.localize.classical import as_flight
from mission.localize.onnx_model import OnnxLocalizer
from mission.localize.preprocess import select_samples
from mission.physics.propagation import make_model
from mission.workshop.dataset import (
    DatasetConfig,
    Randomisation,
    dataset_heights,
    generate_dataset,
    load_dataset,
)
from mission.workshop.train import TrainConfig, train, validation_split


@settings(max_examples=25, deadline=None)
@given(
    s=st.floats(0.3, 3.0),
    seed=st.integers(0, 2**16),
    pattern=st.sampled_from(["dipole", "measured"]),
)
def test_free_space_is_scale_invariant_up_to_friis_constant(s, seed, pattern):
    """Every horizontal offset from the transmitter and the height above it times s: every link
    direction is the same, every distance s times longer, so every RSS drops by exactly 20 log10 s
    (SPEC section 3)."""
    rng = np.random.default_rng(seed)
    m = make_model(
        "free-space", pattern=pattern, rx_heading_rad=rng.uniform(0, 6.28), dtype=np.float64
    )
    tx = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(1, 2)])
    rx = np.column_stack([rng.uniform(-150, 150, (300, 2)), rng.uniform(15, 60, 300)])
    att = rng.normal(0.0, 0.05, (300, 3))
    rx_s = tx + s * (rx - tx)
    d = np.asarray(m.rss_dbm(tx, rx_s, att)) - np.asarray(m.rss_dbm(tx, rx, att))
    np.testing.assert_allclose(d, -20.0 * np.log10(s), atol=1e-6)


def test_ground_reflection_breaks_the_invariance():
    """The limit of the premise: with the two-ray ground reflection the fringes move when scaled (so
    the network trained on scaled coordinates is an approximation, measured in models/README.md, not
    an identity)."""
    rng = np.random.default_rng(1)
    m = make_model("two-ray", dtype=np.float64)
    tx = np.array([0.0, 0.0, 1.5])
    rx = np.column_stack([rng.uniform(-150, 150, (500, 2)), np.full(500, 30.0)])
    d = np.asarray(m.rss_dbm(tx, tx + 1.5 * (rx - tx))) - np.asarray(m.rss_dbm(tx, rx))
    assert np.std(d) > 0.5
    assert abs(np.mean(d) + 20 * np.log10(1.5)) < 1.0  # on average still Friis' constant


@settings(max_examples=40, deadline=None)
@given(
    h=st.one_of(
        st.floats(-100, MIN_HEIGHT_M, exclude_max=True),
        st.just(float("nan")),
        st.just(float("inf")),
    ),
    good=st.lists(st.floats(MIN_HEIGHT_M, 200.0), max_size=4),
)
def test_scale_factor_refuses_heights_that_are_no_cruise(h, good):
    who = f"flight {len(good)}" if good else "the flight"
    with pytest.raises(InputError, match=rf"{who} is .*at least {MIN_HEIGHT_M:.0f} m") as e:
        scale_factor([*good, h])
    assert e.value.field == "height"


def test_scale_factor_and_cluster_scaling():
    np.testing.assert_allclose(
        scale_factor([REFERENCE_HEIGHT_M, 2 * REFERENCE_HEIGHT_M]), [1.0, 0.5]
    )
    f = np.arange(12.0).reshape(2, 6)  # two flights, two clusters each: [p, x, y, p, x, y]
    g = scale_cluster_xy(f, np.array([2.0, 0.5]))
    np.testing.assert_array_equal(g[:, 0::3], f[:, 0::3])  # RSS untouched
    np.testing.assert_array_equal(g[0, [1, 2, 4, 5]], 2.0 * f[0, [1, 2, 4, 5]])
    np.testing.assert_array_equal(g[1, [1, 2, 4, 5]], 0.5 * f[1, [1, 2, 4, 5]])
    assert f[0, 1] == 1.0  # a copy
    # median: ramps do not move it
    assert flight_height(np.array([0.0, 31.0, 31.5, 32.0, 100.0]), 1.5) == 30.0


@pytest.fixture(scope="module")
def tiny_altitude_net(tmp_path_factory, repo_dir):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")

    d = tmp_path_factory.mktemp("alt")
    r = Randomisation(altitude_m=(15.0, 60.0), truncate=(0.15, 0.25))
    generate_dataset(
        DatasetConfig(
            str(repo_dir / "missions" / "spiral.yaml"), 16, seed=3, chunk=8, randomisation=r
        ),
        d / "ds",
        workers=1,
    )
    cfg = TrainConfig(epochs=2, batch_size=8, seed=1, altitude_normalised=True, threads=1)
    res = train([d / "ds"], d / "m.onnx", cfg)
    return d, res


def test_training_flag_writes_the_metadata_that_inference_obeys(tiny_altitude_net):
    d, res = tiny_altitude_net
    assert res.max_onnx_diff < 1e-4
    loc = OnnxLocalizer(res.onnx_path)
    assert loc.needs_heights and loc.reference_height_m == REFERENCE_HEIGHT_M
    a, _ = load_dataset(d / "ds", ("clustering", "tx_enu", "params"))
    h = dataset_heights(a["params"])
    assert np.all((h > 13.0) & (h < 59.0))
    with pytest.raises(InputError, match="height above the transmitter"):
        loc.predict_features(a["clustering"])
    p = loc.predict_features(a["clustering"], h)
    # the validation metric is in metres, not scaled units: recompute it on the same seeded split's
    # flights
    err = np.hypot(*(p - a["tx_enu"][:, :2]).T)

    # the fixture's seed: the split training drew
    val, _ = validation_split(len(h), TrainConfig(seed=1))
    assert res.metrics["val_mean_m"] == pytest.approx(err[val].mean(), rel=1e-3)
    # a metric in scaled units would differ
    assert not np.allclose(scale_factor(h[val]), 1.0, atol=0.05)


def test_other_networks_ignore_heights(repo_dir):
    model = repo_dir / "models" / "rfsl_spiral_e2r.onnx"
    if not model.exists():
        pytest.skip("shipped model absent")
    loc = OnnxLocalizer(model)
    x = np.random.default_rng(0).normal(0.0, 50.0, (4, loc.n_features))
    assert not loc.needs_heights
    np.testing.assert_array_equal(
        loc.predict_features(x, np.full(4, 50.0)), loc.predict_features(x)
    )


def test_normalised_rss_cannot_be_altitude_normalised(tmp_path, tiny_altitude_net):
    d, _ = tiny_altitude_net
    with pytest.raises(InputError, match="clustering") as e:
        train(
            [d / "ds"],
            tmp_path / "n.onnx",
            TrainConfig(features="normalised_rss", altitude_normalised=True),
        )
    assert e.value.field == "--altitude-normalised"


@pytest.fixture(scope="module")
def shipped_alt(repo_dir):
    model = repo_dir / "models" / "rfsl_spiral_alt.onnx"
    if not model.exists():
        pytest.skip("shipped model absent")
    return model


def test_altitude_normalised_prediction_is_scale_equivariant(shipped_alt):
    """A flight k times larger and k times higher is answered k times further from the field origin,
    exactly."""
    loc = OnnxLocalizer(shipped_alt)
    rng = np.random.default_rng(0)
    c = loc.n_features // 3
    feats = np.stack(
        [
            np.sort(rng.uniform(-30, 0, (16, c)))[:, ::-1],
            rng.uniform(0, 300, (16, c)),
            rng.uniform(0, 270, (16, c)),
        ],
        axis=2,
    ).reshape(16, -1)
    h = rng.uniform(15, 60, 16)
    p = loc.predict_features(feats, h)
    assert np.ptp(p, axis=0).min() > 1.0
    for k in (0.5, 1.7):
        pk = loc.predict_features(scale_cluster_xy(feats, np.full(16, k)), k * h)
        np.testing.assert_allclose(pk, k * p, rtol=1e-4, atol=1e-3)


def test_localize_scales_by_the_logs_median_height_above_the_assumed_transmitter(
    tmp_path, shipped_alt
):
    path = write_synthetic_log(tmp_path / "f.csv", alt=45.0)
    loc = OnnxLocalizer(shipped_alt)
    part, _ = select_samples(read_flight_log(path))
    f = as_flight(part, loc.origin)
    got = {}
    for tx_h in (1.5, 4.0):
        est = got[tx_h] = localize_log(path, model_path=shipped_alt, tx_height_m=tx_h)
        want = loc.predict_features(loc.features(f)[None], [np.median(f.enu_m[:, 2]) - tx_h])[0]
        # the log and the model share the origin
        np.testing.assert_allclose([est.x_m, est.y_m], want, atol=0.05)
        assert est.extras["height_above_tx_m"] == pytest.approx(np.median(f.enu_m[:, 2]) - tx_h)
        assert np.median(f.enu_m[:, 2]) == pytest.approx(45.0, abs=0.5)
    # the height matters
    assert abs(got[1.5].x_m - got[4.0].x_m) + abs(got[1.5].y_m - got[4.0].y_m) > 0.1
    assert "note" not in got[1.5].extras  # 45 m is inside its 15-60 m training range


def test_a_flight_too_low_over_the_transmitter_is_a_clear_error(tmp_path, shipped_alt, capsys):
    path = write_synthetic_log(tmp_path / "f.csv", alt=30.0)
    assert main([str(path), "--model", str(shipped_alt), "--tx-height", "27"]) == 2
    err = capsys.readouterr().err
    assert "the flight is 3.0 m above the transmitter" in err and "Traceback" not in err


def test_an_ensemble_keeps_the_normalisation_and_refuses_mixed_members(
    tmp_path, shipped_alt, repo_dir
):
    pytest.importorskip("onnx")

    sys.path.insert(0, str(repo_dir / "models"))

    # a script, importable once its folder is on sys.path (the line above)
    from make_ensemble import build  # noqa: PLC0415

    build(str(tmp_path / "e.onnx"), [str(shipped_alt), str(shipped_alt)])
    ens, one = OnnxLocalizer(tmp_path / "e.onnx"), OnnxLocalizer(shipped_alt)
    feats, h = (
        np.random.default_rng(2).uniform(0, 200, (3, one.n_features)),
        np.array([20.0, 35.0, 50.0]),
    )
    assert ens.needs_heights
    np.testing.assert_allclose(
        ens.predict_features(feats, h), one.predict_features(feats, h), atol=1e-3
    )
    spiral = repo_dir / "models" / "rfsl_spiral_e2r.onnx"
    if spiral.exists():
        with pytest.raises(SystemExit, match="altitude_normalisation"):
            build(str(tmp_path / "bad.onnx"), [str(shipped_alt), str(spiral)])
