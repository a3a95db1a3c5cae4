"""Networks (shapes, parameter and FLOP counts) and a tiny end-to-end training run exported to
ONNX."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime as ort
import pytest

from mission.localize.onnx_model import OnnxLocalizer
from mission.workshop.dataset import DatasetConfig, Randomisation, generate_dataset
from mission.workshop.train import TrainConfig, export_onnx, train

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")


def test_network_shapes_params_flops():
    # torch at its top (noqa): imported once importorskip let the module run
    from mission.workshop.nets import (  # noqa: PLC0415
        NormalisedRssNet,
        RealAdaptRNet,
        count_flops,
        count_parameters,
    )

    net = RealAdaptRNet(60)
    assert net(torch.zeros(5, 60)).shape == (5, 2)
    assert net(torch.zeros(5, 1, 60)).shape == (5, 2)
    assert 150_000 <= count_parameters(net) <= 250_000  # paper: about 0.2 M
    assert 1.0e6 <= count_flops(net, 60) <= 1.6e6  # paper: 1.3 M
    base = NormalisedRssNet(10000)
    assert 6.0e6 <= count_parameters(base) <= 7.5e6  # paper: 6.7 M
    assert 300e6 <= count_flops(base, 10000) <= 420e6  # paper: 332 M
    assert base(torch.zeros(2, 10000)).shape == (2, 2)


def test_tiny_training_exports_matching_onnx(tmp_path, repo_dir):
    r = Randomisation(trajectories=("random_waypoints",), random_params=True, truncate=(0.15, 0.25))
    cfg = DatasetConfig(
        str(repo_dir / "missions" / "spiral.yaml"), 16, seed=3, chunk=8, randomisation=r
    )
    generate_dataset(cfg, tmp_path / "ds", workers=1)
    out = tmp_path / "m.onnx"
    res = train([tmp_path / "ds"], out, TrainConfig(epochs=3, batch_size=8, seed=1, threads=1))
    assert res.max_onnx_diff < 1e-4 and out.exists() and res.metrics["epochs_run"] == 3
    loc = OnnxLocalizer(out)
    assert loc.kind == "clustering" and loc.cfg.c_k == 20
    td = loc.meta["training_data"]
    assert td["datasets"][0]["seed"] == 3 and td["train_config"]["seed"] == 1
    # the card beside it holds the training domain the runtime reads: the dataset's mission altitude
    # (30 m), and no attitude claim for randomised trajectories
    assert loc.card.domain.altitude_m == (30.0, 30.0) and loc.card.domain.attitude_deg is None
    x = np.load(next((tmp_path / "ds").glob("chunk_*.npz")))["clustering"]
    assert np.all(np.isfinite(loc.predict_features(x)))
    # same seed, same weights
    res2 = train(
        [tmp_path / "ds"],
        tmp_path / "m2.onnx",
        TrainConfig(epochs=3, batch_size=8, seed=1, threads=1),
    )
    assert res2.metrics == res.metrics
    hist = json.loads((tmp_path / "m.onnx.train.json").read_text())["history"]
    assert len(hist) == 3
    # a spent time budget stops after the epoch that passed it, and still exports the best epoch
    spent = TrainConfig(epochs=3, batch_size=8, seed=1, max_minutes=0, threads=1)
    res_t = train([tmp_path / "ds"], tmp_path / "t.onnx", spent)
    assert res_t.metrics["epochs_run"] == 1 and (tmp_path / "t.onnx").exists()
    # the normalised-RSS baseline trains and exports too
    nrss = TrainConfig(features="normalised_rss", epochs=1, batch_size=8, threads=1)
    res3 = train([tmp_path / "ds"], tmp_path / "n.onnx", nrss)
    assert OnnxLocalizer(res3.onnx_path).kind == "normalised_rss"


def test_relative_graph_is_translation_equivariant_and_matches_onnxruntime(tmp_path):
    # torch at its top (noqa): imported once importorskip let the module run
    from mission.workshop.nets import CoordinateWrapper, RealAdaptRNet  # noqa: PLC0415

    torch.manual_seed(0)
    inner = RealAdaptRNet(60)
    net = CoordinateWrapper(
        inner,
        torch.tensor([-5.0, 3.0, -2.0] * 20),
        torch.tensor([4.0, 40.0, 35.0] * 20),
        torch.tensor([1.5, -2.0]),
        torch.tensor([12.0, 9.0]),
        relative=True,
    ).eval()
    g = np.random.default_rng(0)
    x = np.zeros((64, 20, 3), np.float32)
    x[:, :, 0] = -np.sort(g.uniform(0, 20, (64, 20)), axis=1)
    x[:, :, 1:] = g.uniform(0, 300, (64, 20, 2))
    x = x.reshape(64, 60)
    path = tmp_path / "rel.onnx"
    meta = {
        "feature_kind": "clustering",
        "feature_config": {},
        "input_normalisation": {
            "input_mean": 0.0,
            "input_std": 1.0,
            "output_mean": 0.0,
            "output_std": 1.0,
        },
        "field_origin": {"lat_deg": 0.0, "lon_deg": 0.0},
    }
    assert export_onnx(net, 60, path, meta, torch.from_numpy(x)) < 1e-4
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    with torch.no_grad():
        ref = net(torch.from_numpy(x)).numpy()
    got = sess.run(None, {"features": x})[0]
    assert np.max(np.abs(got - ref)) < 1e-3  # metres
    for dx, dy in ((37.5, -12.25), (-250.0, 410.0)):
        xs = x.reshape(64, 20, 3).copy()
        xs[:, :, 1] += dx
        xs[:, :, 2] += dy
        shifted = sess.run(None, {"features": xs.reshape(64, 60)})[0]
        assert np.max(np.abs(shifted - got - np.array([dx, dy], np.float32))) < 1e-3
    # the absolute form is not equivariant (sanity check of the test itself)
    net.relative = False
    with torch.no_grad():
        a0 = net(torch.from_numpy(x)).numpy()
        a1 = net(torch.from_numpy(xs.reshape(64, 60))).numpy()
    assert np.max(np.abs(a1 - a0 - np.array([dx, dy]))) > 1.0


def test_tiny_training_relative_metadata_is_identity(tmp_path, repo_dir):
    r = Randomisation(trajectories=("random_waypoints",), random_params=True, truncate=(0.15, 0.25))
    cfg = DatasetConfig(
        str(repo_dir / "missions" / "spiral.yaml"), 12, seed=4, chunk=12, randomisation=r
    )
    generate_dataset(cfg, tmp_path / "ds", workers=1)
    for coords in ("relative", "absolute"):
        out = tmp_path / f"{coords}.onnx"
        res = train(
            [tmp_path / "ds"],
            out,
            TrainConfig(epochs=2, batch_size=4, seed=1, coords=coords, threads=1),
        )
        loc = OnnxLocalizer(out)
        norm = loc.meta["input_normalisation"]
        assert set(norm["input_mean"]) == {0.0} and set(norm["input_std"]) == {1.0}
        assert norm["output_mean"] == [0.0, 0.0] and norm["output_std"] == [1.0, 1.0]
        td = loc.meta["training_data"]
        assert td["coords"] == coords and td["train_config"]["coords"] == coords
        assert res.max_onnx_diff < 1e-4
        x = np.load(next((tmp_path / "ds").glob("chunk_*.npz")))["clustering"]
        assert np.all(np.isfinite(loc.predict_features(x)))
