"""Does profiling the rover's antenna help the self-calibrating search?  (Stop-18 rule: no.)

Why: the AFAR rover carries the same RM-WB1-DN as the UAV; at low elevations its measured gain
varies by ~13 dB with azimuth, an effect the search does not model.  Candidate B scores every
candidate under the product of the UAV-antenna hypotheses (26) and rover hypotheses (isotropic, or
RM-WB1-DN upright at 12 mounting headings), each pair with its own offset; the incumbent A has the
UAV hypotheses only.  Both are scored as the selfcal component of the default fusion, mean(selfcal
point, ``rfsl_spiral_e2r``), on the benchmark (U) and the six real flights (R); rule and outcome in
models/README.md.

    rfsl dataset --suite unseen --logs --n 200 --seed 2026 --out /tmp/suite_2026
    # ~1 min
    python experiments/rover_hypotheses.py --suite-dir /tmp/suite_2026 \
        --mat ../shared/data/afar2023/mat

The product SSR per (UAV hypothesis h, rover hypothesis t, candidate k) comes from sufficient
statistics with one batched matmul per candidate chunk: SSR = S2_h - 2 X_ht + T2_t - (S1_h - T1_t)^2
/ M, X_ht = sum_m r_hm g_tm.
"""

from __future__ import annotations

import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

# the command line and flight loading it shares with the benchmarks (benchmarks/_scoring.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _scoring import flight_with_truth, scoring_parser

from mission.localize import selfcal as sc
from mission.localize.api import localize_log, search_area
from mission.localize.preprocess import select_samples
from mission.physics.antenna import rm_wb1_dn
from mission.threads import limit_worker
from mission.workshop.evaluate import import_afar

ROVER_HEADINGS = (None, *range(0, 360, 30))  # None = isotropic rover antenna
_UAV_HYPOTHESES = sc.antenna_hypotheses


def product_hypotheses(kinds=sc.HYPOTHESIS_KINDS, heading_step_deg: float = 30.0) -> list[tuple]:
    """UAV hypotheses x rover hypotheses as 5-tuples (label, pattern, heading rad, flipped, rover
    heading deg)."""
    return [
        (lab + ("" if t is None else f" + rover RM-WB1-DN heading {t}"), pat, head, fl, t)
        for t in ROVER_HEADINGS
        for (lab, pat, head, fl) in _UAV_HYPOTHESES(kinds, heading_step_deg)
    ]


def product_ssr(cand_xy: np.ndarray, cells, hyps, tx_height_m: float, chunk: int = 256):
    """Drop-in for ``selfcal.hypothesis_ssr`` over ``product_hypotheses``: SSR and offset (H*T,
    K)."""
    uav = list(dict.fromkeys(h[:4] for h in hyps))
    rover = list(dict.fromkeys(h[4] for h in hyps))
    iu = {h: i for i, h in enumerate(uav)}
    it = {t: i for i, t in enumerate(rover)}
    k_all, m = len(cand_xy), len(cells)
    ssr = np.empty((len(uav), len(rover), k_all))
    off = np.empty_like(ssr)
    look_rover = sc.GainLookup(rm_wb1_dn())
    y = cells.rss_dbm.astype(np.float32)[None, :]
    for s in range(0, k_all, chunk):
        cx = cand_xy[s : s + chunk]
        pg, el, az = sc._geometry(cx, cells, tx_height_m)
        base = y - pg
        r = np.stack(list(sc.hypothesis_residuals(base, el, az, uav)))
        # the rover sees the UAV at elevation -el (up-positive) and world azimuth candidate -> cell
        azw = np.arctan2(
            cells.enu_m[None, :, 0] - cx[:, None, 0], cells.enu_m[None, :, 1] - cx[:, None, 1]
        )
        tidx = sc.flat_index(-el, azw)
        g = np.zeros((len(rover), len(cx), m), np.float32)
        for t in rover:
            if t is not None:
                g[it[t]] = look_rover.gain_db(tidx, t, False)
        mu = r.mean(axis=2)
        r -= mu[:, :, None]  # centred: float32 sums stay small
        s2 = np.einsum("hkm,hkm->hk", r, r).astype(np.float64)
        t1 = g.sum(axis=2).astype(np.float64)
        t2 = np.einsum("tkm,tkm->tk", g, g).astype(np.float64)
        x = (
            np.matmul(r.transpose(1, 0, 2), g.transpose(1, 2, 0))
            .astype(np.float64)
            .transpose(1, 2, 0)
        )
        ssr[:, :, s : s + chunk] = s2[:, None] - 2.0 * x + t2[None] - t1[None] ** 2 / m
        off[:, :, s : s + chunk] = mu[:, None, :] - t1[None] / m
    rows = [(iu[h[:4]], it[h[4]]) for h in hyps]
    return (
        np.maximum(np.stack([ssr[i, t] for i, t in rows]), 0.0),
        np.stack([off[i, t] for i, t in rows]),
    )


def one(job: tuple[str, str, int, str]) -> dict:
    """Selfcal (A or B) and the fusion's network on one flight: points, truth, the truth's HPD
    level."""
    kind, src, i, cand = job
    log, truth = flight_with_truth(kind, src, i)
    net = localize_log(log, model_path="models/rfsl_spiral_e2r.onnx")
    sc.antenna_hypotheses, sc.hypothesis_ssr = (
        (product_hypotheses, product_ssr) if cand == "B" else (_UAV_HYPOTHESES, _ORIG_SSR)
    )
    part, _ = select_samples(log)
    t0 = time.process_time()
    est = sc.SelfCalibratingGrid(area=search_area(log)).predict(part)
    return {
        "xy": np.array([est.x_m, est.y_m]),
        "net": np.array([net.x_m, net.y_m]),
        "truth": truth,
        "q": est.posterior.hpd_level(float(truth[0]), float(truth[1])),
        "cpu_s": time.process_time() - t0,
    }


_ORIG_SSR = sc.hypothesis_ssr


def main() -> None:
    args = scoring_parser(__doc__).parse_args()

    res: dict[str, dict[str, list]] = {}
    with (
        tempfile.TemporaryDirectory() as tmp,
        ProcessPoolExecutor(args.workers, initializer=limit_worker) as ex,
    ):
        real = [str(p) for p in import_afar(args.mat, tmp)]
        for cand in ("A", "B"):
            res[cand] = {
                "R": list(ex.map(one, [("real", p, 0, cand) for p in real])),
                "U": list(
                    ex.map(
                        one,
                        [("suite", args.suite_dir, i, cand) for i in range(args.n)],
                        chunksize=4,
                    )
                ),
            }

    def err(rows, fused=True):
        return np.array(
            [
                np.hypot(*((0.5 * (r["xy"] + r["net"]) if fused else r["xy"]) - r["truth"]))
                for r in rows
            ]
        )

    u = {c: err(res[c]["U"]).mean() for c in res}
    r = {c: err(res[c]["R"]).mean() for c in res}
    for c in res:
        eu, er = err(res[c]["U"]), err(res[c]["R"])
        cov = np.mean([x["q"] < sc.CALIBRATED_MASS[0.9] for x in res[c]["U"]])
        held = sum(x["q"] < sc.CALIBRATED_MASS[0.9] for x in res[c]["R"])
        print(
            f"{c}: fusion U {eu.mean():.1f} / {np.median(eu):.1f} / "
            f"{np.percentile(eu, 90):.1f}  R {er.mean():.1f}"
            f"  score {u[c] / min(u.values()) + r[c] / min(r.values()):.3f}  in 90 %: "
            f"{100 * cov:.1f} % of U, "
            f"{held} of {len(er)} real  | selfcal alone U {err(res[c]['U'], False).mean():.1f} R "
            f"{err(res[c]['R'], False).mean():.1f}  | R per flight "
            f"{' '.join(f'{e:.1f}' for e in er)}  | CPU s "
            f"per flight {np.mean([x['cpu_s'] for x in res[c]['U']]):.2f}"
        )


if __name__ == "__main__":
    main()
