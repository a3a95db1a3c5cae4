"""Write ``models/<name>.json``: the CI check (dataset config + metrics of the shipped model on it)
and the evaluation reports (``rfsl evaluate --out`` JSON files) that the model card quotes, and the
training domain (``mission.workshop.domain``: altitude and attitude spans) that ``localize`` reads
from it.

    python models/write_card_json.py models/NAME.onnx CI_DATASET models/NAME.json [REPORT.json ...]

``CI_DATASET`` is a small simulated set written by ``rfsl dataset`` (the card uses ``rfsl dataset
missions/spiral.yaml --n 200 --seed 2000 --model e2r --features clustering --out DIR``);
``tests/test_shipped_model.py`` regenerates it from the recorded configuration and checks the
metrics.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from mission.localize.card import DOMAIN_KEY, REGIONS_KEY
from mission.localize.onnx_model import OnnxLocalizer
from mission.workshop.dataset import dataset_heights, load_dataset
from mission.workshop.domain import training_domain


def main(argv: list[str]) -> int:
    model, ci_ds, out = argv[:3]
    loc = OnnxLocalizer(model)
    arrays, m = load_dataset(ci_ds, (loc.kind, "tx_enu", "params"))
    pred = loc.predict_features(arrays[loc.kind], dataset_heights(arrays["params"]))
    err = np.hypot(*(pred - arrays["tx_enu"][:, :2]).T)
    cfg = dict(m["config"])
    if cfg.get("mission"):  # suite-family sets (rfsl dataset --suite) have no mission
        cfg["mission"] = "missions/" + Path(cfg["mission"]).name
    card = {
        "model": Path(model).name,
        "ci_check": {
            "dataset_config": cfg,
            "tolerance": 0.05,
            "metrics": {
                "mean_m": float(err.mean()),
                "median_m": float(np.median(err)),
                "p90_m": float(np.percentile(err, 90)),
            },
            "command": "pytest tests/test_shipped_model.py",
        },
        "training": loc.meta.get("training_data"),
        "evaluations": [json.loads(Path(r).read_text()) for r in argv[3:]],
    }
    # what the runtime checks
    card[DOMAIN_KEY] = training_domain(loc.meta.get("training_data")).to_dict()
    # the error circles' calibration (error_circles) stays; it names the model's digest
    if Path(out).is_file():
        old = json.loads(Path(out).read_text())
        if REGIONS_KEY in old:
            card[REGIONS_KEY] = old[REGIONS_KEY]
    Path(out).write_text(json.dumps(card, indent=1) + "\n")
    print(card["ci_check"]["metrics"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
