"""The shipped model reproduces its model card's simulated-test metrics (within 5 %).

``models/rfsl_default.json`` records the exact dataset configuration (seed, mission, model) of a small
simulated test set and the metrics the shipped model reached on it; the test regenerates that set
(bytes depend only on the seed) and recomputes the metrics with onnxruntime only.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from mission.localize.dataset import DatasetConfig, generate_dataset, load_dataset


@pytest.mark.slow
def test_shipped_model_reproduces_card(tmp_path, repo_dir):
    model = repo_dir / "models" / "rfsl_default.onnx"
    card = repo_dir / "models" / "rfsl_default.json"
    if not model.exists() or not card.exists():
        pytest.skip("no shipped model")
    from mission.localize.onnx_model import OnnxLocalizer

    assert model.stat().st_size < 5 * 2**20
    rec = json.loads(card.read_text())["ci_check"]
    cfg = DatasetConfig.from_dict(rec["dataset_config"])
    cfg = replace(cfg, mission=str(repo_dir / cfg.mission))
    generate_dataset(cfg, tmp_path / "ds", workers=2)
    loc = OnnxLocalizer(model)
    arrays, m = load_dataset(tmp_path / "ds", (loc.kind, "tx_enu"))
    assert m["feature_config"] == loc.cfg.to_dict()
    pred = loc.predict_features(arrays[loc.kind])
    err = np.hypot(*(pred - arrays["tx_enu"][:, :2]).T)
    got = {
        "mean_m": float(err.mean()),
        "median_m": float(np.median(err)),
        "p90_m": float(np.percentile(err, 90)),
    }
    for k, want in rec["metrics"].items():
        assert got[k] == pytest.approx(want, rel=rec.get("tolerance", 0.05)), (k, got, rec["metrics"])
