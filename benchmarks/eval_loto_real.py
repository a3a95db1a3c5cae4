"""Leave-one-team-out (LOTO) scores on the six real AFAR flights: nothing is scored by a model whose physics
saw the flight's team.

Usage::

    python benchmarks/eval_loto_real.py --net-fit328 M/afar_fit328.onnx --net-fit288 M/afar_fit288.onnx \
        [--data ../shared/data/afar2023/mat] [--json OUT.json]

Rows (error per flight in metres, then mean/median over six flights and over the five without the suspect
team-288 location 3):

- ``grid LOTO``: model-based grid search with the fold preset fitted on the *other* team
  (``afar:fit328`` for team 288's flights, ``afar:fit288`` for team 328's);
- ``net LOTO``: the network trained on data simulated with that same held-out fold physics;
- ``mean(grid, net) LOTO``: the plain average of the two estimates (declared before scoring; no weights);
- ``net all-five`` (``--net-all``, optional): a network whose physics was fitted on all five flights; it is
  NOT a held-out figure and is printed for reference only.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from mission.importers.afar import AFAR2023_TRUTH

SUSPECT = "288_loc_3"
FOLD_FOR_TEAM = {"288": "fit328", "328": "fit288"}  # the fold whose physics did not see this team


def _row(name: str, errs: list[float], flights: list[str]) -> dict:
    e = np.array(errs)
    ok = np.array([n != SUSPECT for n in flights])
    return {"method": name, "per_flight_m": dict(zip(flights, map(float, e), strict=True)),
            "mean6_m": float(e.mean()), "median6_m": float(np.median(e)),
            "mean5_m": float(e[ok].mean()), "median5_m": float(np.median(e[ok]))}


def main() -> None:
    from mission.importers.afar import import_afar_mat
    from mission.localize.api import localize_log

    default = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "afar2023" / "mat"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(default))
    ap.add_argument("--net-fit328", required=True, help="network trained on afar:fit328 physics (scores team 288)")
    ap.add_argument("--net-fit288", required=True, help="network trained on afar:fit288 physics (scores team 328)")
    ap.add_argument("--net-all", help="optional network trained on the all-five-flight preset (not held out)")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args()
    nets = {"fit328": args.net_fit328, "fit288": args.net_fit288}
    files = sorted(Path(args.data).glob("results_useful_ori_exp_*_loc_*.mat"))
    if not files:
        raise SystemExit(f"no AFAR MAT files under {args.data}")
    cols: dict[str, list[float]] = {"grid LOTO": [], "net LOTO": [], "mean(grid, net) LOTO": []}
    if args.net_all:
        cols["net all-five (not held out)"] = []
    flights = []
    with tempfile.TemporaryDirectory() as tmp:
        for f in files:
            name = f.stem.replace("results_useful_ori_exp_", "")
            team, loc = name.split("_")[0], int(name.rsplit("_", 1)[1])
            log = import_afar_mat(f, tmp, truth=AFAR2023_TRUTH[loc]).out_path
            fold = FOLD_FOR_TEAM[team]
            g = localize_log(log, method="grid", physics_preset=f"afar:{fold}")
            n = localize_log(log, method="onnx", model_path=nets[fold])
            tx, ty = g.extras["truth_x_m"], g.extras["truth_y_m"]
            mx, my = 0.5 * (g.x_m + n.x_m), 0.5 * (g.y_m + n.y_m)
            cols["grid LOTO"].append(g.error_m)
            cols["net LOTO"].append(n.error_m)
            cols["mean(grid, net) LOTO"].append(float(np.hypot(mx - tx, my - ty)))
            if args.net_all:
                cols["net all-five (not held out)"].append(localize_log(log, method="onnx",
                                                                        model_path=args.net_all).error_m)
            flights.append(name)
    rows = [_row(k, v, flights) for k, v in cols.items()]
    print(f"{'method':30s}" + "".join(f"{n:>11s}" for n in flights) + f"{'mean6':>8s}{'med6':>7s}{'mean5':>8s}"
          f"{'med5':>7s}")
    for r in rows:
        print(f"{r['method']:30s}" + "".join(f"{v:11.1f}" for v in r["per_flight_m"].values())
              + f"{r['mean6_m']:8.1f}{r['median6_m']:7.1f}{r['mean5_m']:8.1f}{r['median5_m']:7.1f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "nets": nets, "net_all": args.net_all}, indent=1))


if __name__ == "__main__":
    main()
