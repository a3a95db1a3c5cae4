"""The real-log default reproduces its card on the six shared AFAR flights
(``models/real_default.json``).

Why: the default's figures in ``models/README.md`` are the project's claim about real flights; a
change to the self-calibrating search, the fusion, the shipped network or the sample selection that
moves them must re-record the card (and say so), not drift silently.  Skipped where ``../shared`` is
absent.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from mission.importers.afar import afar2023_id
from mission.localize.api import localize_log
from mission.localize.uncertainty import region_covers
from mission.workshop.evaluate import import_afar


@pytest.mark.real
def test_real_default_reproduces_its_card(tmp_path, shared_dir, repo_dir) -> None:
    card = json.loads((repo_dir / "models" / "real_default.json").read_text())
    tol = card["tolerance_m"]
    logs = {
        afar2023_id(p): p for p in import_afar(shared_dir / "data" / "afar2023" / "mat", tmp_path)
    }
    assert set(logs) == {afar2023_id(n) for n in card["flights"]} and len(logs) == 6
    for name, want in card["flights"].items():
        est = localize_log(logs[afar2023_id(name)])
        assert est.method == card["method"], name
        assert est.error_m == pytest.approx(want["error_m"], abs=tol), name
        t = (est.extras["truth_x_m"], est.extras["truth_y_m"])
        assert (region_covers(est, *t, 0.5), region_covers(est, *t, 0.9)) == (
            want["in_50"],
            want["in_90"],
        ), name
        for comp, err in want["components_error_m"].items():
            cx, cy = est.extras["components"][comp]
            assert float(np.hypot(cx - t[0], cy - t[1])) == pytest.approx(err, abs=tol), (
                name,
                comp,
            )
