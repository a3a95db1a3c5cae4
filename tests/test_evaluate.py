"""Evaluation: the table rows on a small simulated test set and on two real AFAR flights."""

from __future__ import annotations

import numpy as np
import pytest

from mission.localize.evaluate import afar_truth, evaluate_real, evaluate_sim, import_afar


def test_afar_truth_from_name():
    t, caveat = afar_truth("results_useful_ori_exp_288_loc_3.csv")
    assert t == pytest.approx((35.72985129, -78.69711002)) and "suspect" in caveat
    assert afar_truth("results_useful_ori_exp_328_loc_1.mat")[1] is None
    assert afar_truth("other.csv") == (None, None)


def test_evaluate_sim_classical(tmp_path, repo_dir):
    from mission.localize.dataset import DatasetConfig, Randomisation, generate_dataset

    r = Randomisation(trajectories=("random_waypoints",), random_params=True, truncate=(0.2, 0.3))
    generate_dataset(
        DatasetConfig(
            str(repo_dir / "missions" / "spiral.yaml"), 3, seed=2, randomisation=r, features=("clustering",)
        ),
        tmp_path / "ds",
    )
    rows = evaluate_sim([], tmp_path / "ds", ("strongest", "centroid"), n_classical=3)
    assert [r.method for r in rows] == ["strongest", "centroid"]
    s = rows[0].summary()
    assert s["n"] == 3 and 0 <= s["median_m"] <= s["p90_m"] < 500


@pytest.mark.real
def test_evaluate_real_two_afar_flights(tmp_path, shared_dir, repo_dir):
    mats = shared_dir / "data" / "afar2023" / "mat"
    src = tmp_path / "mat"
    src.mkdir()
    for name in ("results_useful_ori_exp_328_loc_1.mat", "results_useful_ori_exp_328_loc_2.mat"):
        (src / name).symlink_to(mats / name)
    logs = import_afar(src, tmp_path / "logs")
    models = [m for m in [repo_dir / "models" / "rfsl_default.onnx"] if m.exists()]
    rows = evaluate_real(models, logs, ("strongest",))
    by = {r.method: r for r in rows}
    e = np.array(by["strongest"].errors)
    assert e.shape == (2,) and np.all(e < 60)  # strongest sample is within tens of metres here
    if models:
        assert np.all(np.array(rows[0].errors) < 100)
