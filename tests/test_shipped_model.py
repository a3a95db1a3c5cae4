"""The shipped models reproduce their model card's simulated-test metrics (within 5 %).

``models/<name>.json`` records the exact dataset configuration (seed, mission, model) of a small simulated
test set and the metrics the shipped model ``models/<name>.onnx`` reached on it; the test regenerates that
set (bytes depend only on the seed; models sharing a configuration share one regeneration) and recomputes
the metrics with onnxruntime only.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np
import pytest

from mission.localize.dataset import DatasetConfig, generate_dataset, load_dataset

SHIPPED = ("rfsl_default", "rfsl_spiral_e2r", "rfsl_afar")


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory):
    """Dataset folder for a ci_check dataset_config, generated once per distinct configuration."""
    cache: dict[str, object] = {}

    def get(cfg: DatasetConfig):
        key = hashlib.sha256(json.dumps(cfg.to_dict(), sort_keys=True).encode()).hexdigest()[:16]
        if key not in cache:
            d = tmp_path_factory.mktemp(f"ci_{key}") / "ds"
            generate_dataset(cfg, d, workers=2)
            cache[key] = d
        return cache[key]

    return get


@pytest.mark.slow
@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_model_reproduces_card(name, regenerated, repo_dir):
    model = repo_dir / "models" / f"{name}.onnx"
    card = repo_dir / "models" / f"{name}.json"
    if not model.exists() or not card.exists():
        pytest.skip(f"no shipped model {name}")
    from mission.localize.onnx_model import OnnxLocalizer

    assert model.stat().st_size < 5 * 2**20
    rec = json.loads(card.read_text())["ci_check"]
    cfg = DatasetConfig.from_dict(rec["dataset_config"])
    if cfg.mission:
        cfg = replace(cfg, mission=str(repo_dir / cfg.mission))
    ds = regenerated(cfg)
    loc = OnnxLocalizer(model)
    arrays, m = load_dataset(ds, (loc.kind, "tx_enu"))
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
