"""Leave-one-team-out (LOTO) scores on the six real AFAR flights: nothing is scored by a model whose
physics saw the flight's team.

Usage::

    python benchmarks/eval_loto_real.py --net-fit328 M/afar_fit328.onnx \
        --net-fit288 M/afar_fit288.onnx [--data ../shared/data/afar2023/mat] [--json OUT.json]
    python benchmarks/eval_loto_real.py --nets models/rfsl_family.onnx models/rfsl_spiral_e2r.onnx

Rows (error per flight in metres, then mean/median over six flights and over the five without the
suspect team-288 location 3):

- ``grid LOTO``: model-based grid search with the fold preset fitted on the *other* team
  (``afar:fit328`` for team 288's flights, ``afar:fit288`` for team 328's);
- ``net LOTO``: the network trained on data simulated with that same held-out fold physics;
- ``mean(grid, net) LOTO``: the plain average of the two estimates (declared before scoring; no
  weights);
- ``net NAME (no real flight)`` (``--nets``): networks whose training physics never saw a real
  flight (the ``generic`` unseen-suite family, the e2r networks): held out on every flight by
  construction, scored on all six; with ``mean(grid LOTO, NAME)`` beside each;
- ``net all-five`` (``--net-all``, optional): a network whose physics was fitted on all five
  flights; it is NOT a held-out figure and is printed for reference only.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from mission.importers.afar import (
    AFAR2023_FOLD_WITHOUT,
    AFAR2023_TRUTH,
    import_afar_mat,
    is_afar2023_suspect,
)
from mission.localize.api import localize_log


def _row(name: str, errs: list[float], flights: list[str]) -> dict:
    e = np.array(errs)
    ok = np.array([not is_afar2023_suspect(n) for n in flights])
    return {
        "method": name,
        "per_flight_m": dict(zip(flights, map(float, e), strict=True)),
        "mean6_m": float(e.mean()),
        "median6_m": float(np.median(e)),
        "mean5_m": float(e[ok].mean()),
        "median5_m": float(np.median(e[ok])),
    }


def main() -> None:
    default = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "afar2023" / "mat"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(default))
    ap.add_argument("--net-fit328", help="network trained on afar:fit328 physics (scores team 288)")
    ap.add_argument("--net-fit288", help="network trained on afar:fit288 physics (scores team 328)")
    ap.add_argument(
        "--nets", nargs="*", default=[], help="networks trained without any real-flight physics"
    )
    ap.add_argument(
        "--net-all", help="optional network trained on the all-five-flight preset (not held out)"
    )
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args()
    if (args.net_fit328 is None) != (args.net_fit288 is None):
        raise SystemExit("give both --net-fit328 and --net-fit288, or neither")
    nets = {"fit328": args.net_fit328, "fit288": args.net_fit288} if args.net_fit328 else {}
    files = sorted(Path(args.data).glob("results_useful_ori_exp_*_loc_*.mat"))
    if not files:
        raise SystemExit(f"no AFAR MAT files under {args.data}")
    cols: dict[str, list[float]] = {"grid LOTO": []}
    if nets:
        cols.update({"net LOTO": [], "mean(grid, net) LOTO": []})
    for p in args.nets:
        cols.update(
            {f"net {Path(p).stem} (no real flight)": [], f"mean(grid LOTO, {Path(p).stem})": []}
        )
    if args.net_all:
        cols["net all-five (not held out)"] = []
    flights = []
    with tempfile.TemporaryDirectory() as tmp:
        for f in files:
            name = f.stem.replace("results_useful_ori_exp_", "")
            team, loc = name.split("_")[0], int(name.rsplit("_", 1)[1])
            log = import_afar_mat(f, tmp, truth=AFAR2023_TRUTH[loc]).out_path
            fold = AFAR2023_FOLD_WITHOUT[team]
            g = localize_log(log, method="grid", physics_preset=f"afar:{fold}")
            tx, ty = g.extras["truth_x_m"], g.extras["truth_y_m"]
            cols["grid LOTO"].append(g.error_m)
            for label, path in ([("net LOTO", nets[fold])] if nets else []) + [
                (f"net {Path(p).stem} (no real flight)", p) for p in args.nets
            ]:
                n = localize_log(log, method="onnx", model_path=path)
                mean = (
                    "mean(grid, net) LOTO"
                    if label == "net LOTO"
                    else f"mean(grid LOTO, {Path(path).stem})"
                )
                cols[label].append(n.error_m)
                cols[mean].append(
                    float(np.hypot(0.5 * (g.x_m + n.x_m) - tx, 0.5 * (g.y_m + n.y_m) - ty))
                )
            if args.net_all:
                cols["net all-five (not held out)"].append(
                    localize_log(log, method="onnx", model_path=args.net_all).error_m
                )
            flights.append(name)
    rows = [_row(k, v, flights) for k, v in cols.items()]
    print(
        f"{'method':42s}"
        + "".join(f"{n:>11s}" for n in flights)
        + f"{'mean6':>8s}{'med6':>7s}{'mean5':>8s}"
        f"{'med5':>7s}"
    )
    for r in rows:
        print(
            f"{r['method']:42s}"
            + "".join(f"{v:11.1f}" for v in r["per_flight_m"].values())
            + f"{r['mean6_m']:8.1f}{r['median6_m']:7.1f}{r['mean5_m']:8.1f}{r['median5_m']:7.1f}"
        )
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                {"rows": rows, "nets": nets, "no_real_nets": args.nets, "net_all": args.net_all},
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
