"""The real-log default reproduces its card on the six shared AFAR flights (``models/real_default.json``).

Why: the default's figures in ``models/README.md`` are the project's claim about real flights; a change to the
self-calibrating search, the fusion, the shipped network or the sample selection that moves them must re-record
the card (and say so), not drift silently.  Skipped where ``../shared`` is absent.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from mission.importers.afar import AFAR2023_TRUTH, import_afar_mat
from mission.localize.api import localize_log
from mission.localize.uncertainty import region_covers


@pytest.mark.real
def test_real_default_reproduces_its_card(tmp_path, shared_dir, repo_dir) -> None:
    card = json.loads((repo_dir / "models" / "real_default.json").read_text())
    tol = card["tolerance_m"]
    assert len(card["flights"]) == 6
    for name, want in card["flights"].items():
        team, loc = name.split("_loc_")
        mat = shared_dir / "data" / "afar2023" / "mat" / f"results_useful_ori_exp_{team}_loc_{loc}.mat"
        log = import_afar_mat(mat, tmp_path, truth=AFAR2023_TRUTH[int(loc)]).out_path
        est = localize_log(log)
        assert est.method == card["method"], name
        assert est.error_m == pytest.approx(want["error_m"], abs=tol), name
        t = (est.extras["truth_x_m"], est.extras["truth_y_m"])
        assert (region_covers(est, *t, 0.5), region_covers(est, *t, 0.9)) == (want["in_50"], want["in_90"]), name
        for comp, err in want["components_error_m"].items():
            cx, cy = est.extras["components"][comp]
            assert float(np.hypot(cx - t[0], cy - t[1])) == pytest.approx(err, abs=tol), (name, comp)
