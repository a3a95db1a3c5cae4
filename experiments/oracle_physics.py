"""What does self-calibration cost?  The grid search given each benchmark flight's *true* physics,
and with one piece of that knowledge removed at a time, against the self-calibrating search on the
same flights.

Why: the self-calibrating search knows neither the UAV antenna (it profiles 26 hypotheses) nor the
path-gain slope, the ground, the rover's antenna or the roll/pitch coupling.  The oracle knows all
of them and only the shadowing and noise realisations and the offset are unknown to it, so its error
is what the benchmark's shadowing and geometry leave to any model-based method, and the rungs say
which knowledge is worth most.

    rfsl dataset --suite unseen --logs --n 200 --seed 2026 --out /tmp/suite_2026
    python experiments/oracle_physics.py --suite-dir /tmp/suite_2026          # ~2 min on 2 cores
"""

from __future__ import annotations

import argparse
import copy
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from mission.localize import classical
from mission.localize.api import localize_log, search_area
from mission.localize.preprocess import select_samples
from mission.physics.presets import build_model
from mission.threads import limit_worker
from mission.workshop.suite_cache import read_suite

# each rung removes its knowledge from the true spec; "known antenna only" removes all four
RUNGS = (
    "oracle",
    "no path-gain slope",
    "no ground reflection",
    "isotropic rover",
    "yaw only",
    "known antenna only",
)


def degraded(spec: dict, rung: str) -> dict:
    """The true physics spec with the rung's knowledge removed."""
    s = copy.deepcopy(spec)
    every = rung == "known antenna only"
    if every or rung == "no path-gain slope":
        s.pop("path_gain_slope", None)
    if every or rung == "no ground reflection":
        s["ground"] = None
    if every or rung == "isotropic rover":
        s["tx_pattern"], s["tx_heading_deg"] = "isotropic", 0.0
    if every or rung == "yaw only":
        s["attitude"] = "yaw"
    return s


def one(job: tuple[str, int]) -> dict:
    """Errors (m) of every rung and of the self-calibrating search on one benchmark flight."""
    src, i = job
    fl = read_suite(src).load(i)
    d, truth = fl.draw, np.asarray(fl.truth_xy)
    part, _ = select_samples(fl.log)
    area = search_area(fl.log)
    out = {"outside": bool(d["tx_outside_flight_area"])}
    for rung in RUNGS:
        model = build_model(degraded(d["physics"]["spec"], rung), name=rung)
        # the search's assumed height
        tx_h = 1.5 if rung == "known antenna only" else d["tx_height_m"]
        e = classical.ModelGridSearch(model, tx_height_m=tx_h, area=area).predict(part)
        out[rung] = float(np.hypot(e.x_m - truth[0], e.y_m - truth[1]))
    e = localize_log(fl.log, method="selfcal")
    out["selfcal"] = float(np.hypot(e.x_m - truth[0], e.y_m - truth[1]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--suite-dir", required=True)
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    with ProcessPoolExecutor(args.workers, initializer=limit_worker) as ex:
        rows = list(ex.map(one, [(args.suite_dir, i) for i in range(args.n)], chunksize=2))
    out = np.array([r["outside"] for r in rows])
    print(
        f"{'':22s} mean / median (all {len(rows)})   inside ({(~out).sum()})   outside "
        f"({out.sum()})"
    )
    for k in (*RUNGS, "selfcal"):
        e = np.array([r[k] for r in rows])
        print(
            f"{k:22s} {e.mean():6.1f} / {np.median(e):5.1f}   {e[~out].mean():6.1f}   "
            f"{e[out].mean():6.1f}"
        )


if __name__ == "__main__":
    main()
