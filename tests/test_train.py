"""Networks (shapes, parameter and FLOP counts) and a tiny end-to-end training run exported to ONNX."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")


def test_network_shapes_params_flops():
    from mission.localize.nets import NormalisedRssNet, RealAdaptRNet, count_flops, count_parameters

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
    from mission.localize.dataset import DatasetConfig, Randomisation, generate_dataset
    from mission.localize.onnx_model import OnnxLocalizer
    from mission.localize.train import TrainConfig, train

    r = Randomisation(trajectories=("random_waypoints",), random_params=True, truncate=(0.15, 0.25))
    cfg = DatasetConfig(str(repo_dir / "missions" / "spiral.yaml"), 16, seed=3, chunk=8, randomisation=r)
    generate_dataset(cfg, tmp_path / "ds", workers=1)
    out = tmp_path / "m.onnx"
    res = train([tmp_path / "ds"], out, TrainConfig(epochs=3, batch_size=8, seed=1))
    assert res.max_onnx_diff < 1e-4 and out.exists() and res.metrics["epochs_run"] == 3
    loc = OnnxLocalizer(out)
    assert loc.kind == "clustering" and loc.cfg.c_k == 20
    td = loc.meta["training_data"]
    assert td["datasets"][0]["seed"] == 3 and td["train_config"]["seed"] == 1
    x = np.load(next((tmp_path / "ds").glob("chunk_*.npz")))["clustering"]
    assert np.all(np.isfinite(loc.predict_features(x)))
    # same seed, same weights
    res2 = train([tmp_path / "ds"], tmp_path / "m2.onnx", TrainConfig(epochs=3, batch_size=8, seed=1))
    assert res2.metrics == res.metrics
    hist = json.loads((tmp_path / "m.onnx.train.json").read_text())["history"]
    assert len(hist) == 3
    # the normalised-RSS baseline trains and exports too
    res3 = train(
        [tmp_path / "ds"], tmp_path / "n.onnx", TrainConfig(features="normalised_rss", epochs=1, batch_size=8)
    )
    assert OnnxLocalizer(res3.onnx_path).kind == "normalised_rss"
