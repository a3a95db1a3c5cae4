"""Benchmark: ``localize`` on a 20 000-sample flight (features + ONNX inference; the real-log default), after start-up.

Start-up (importing, loading the ONNX session, first k-means call) is timed once; then the per-flight
work -- clustering features of the whole flight and one onnxruntime call -- is timed ``--repeat`` times
(median reported; target < 100 ms).  The full ``localize_log`` path (CSV read, cruise selection, frame
conversion) is timed as well for reference.

    python benchmarks/bench_localize.py [--model models/rfsl_default.onnx] [--samples 20000]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def simulated_flight(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A spiral flight of the default mission, flown repeatedly until it has ``n`` samples (ENU, att, RSS)."""
    from mission.physics import make_model
    from mission.simulate import simulate_flight
    from mission.spec import load_mission

    spec = load_mission(REPO / "missions" / "spiral.yaml")
    rng = np.random.default_rng(seed)
    tx = np.array([120.0, 180.0, 1.5])
    fl = simulate_flight(spec.waypoints_enu(), tx, make_model("e2r"), spec.sim_config(), rng)
    reps = int(np.ceil(n / len(fl.rss_dbm)))
    take = np.tile(np.arange(len(fl.rss_dbm)), reps)[:n]
    return fl.enu[take], fl.attitude_rad[take], fl.rss_dbm[take], fl, spec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(REPO / "models" / "rfsl_default.onnx"))
    ap.add_argument("--samples", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=10)
    args = ap.parse_args()
    t0 = time.perf_counter()
    from mission.localize.onnx_model import OnnxLocalizer

    loc = OnnxLocalizer(args.model)
    enu, att, rss, fl, spec = simulated_flight(args.samples)
    loc.predict((enu, rss, att))  # warm-up: first k-means / session run
    startup = time.perf_counter() - t0
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        loc.predict((enu, rss, att))
        times.append(time.perf_counter() - t)
    feat_t, inf_t = [], []
    for _ in range(args.repeat):
        t = time.perf_counter()
        f = loc.features(
            __import__("mission.localize.classical", fromlist=["as_flight"]).as_flight((enu, rss, att))
        )
        t1 = time.perf_counter()
        loc.predict_features(f[None, :])
        feat_t.append(t1 - t)
        inf_t.append(time.perf_counter() - t1)
    print(f"model {Path(args.model).name} ({loc.kind}); flight of {len(rss)} samples")
    print(f"start-up (imports, session, simulated flight, warm-up): {startup:.2f} s")
    print(
        f"features + inference: median {1e3 * statistics.median(times):.1f} ms "
        f"(min {1e3 * min(times):.1f}, max {1e3 * max(times):.1f}) over {args.repeat} runs; target < 100 ms"
    )
    print(
        f"  of which features {1e3 * statistics.median(feat_t):.1f} ms, "
        f"onnxruntime {1e3 * statistics.median(inf_t):.2f} ms"
    )
    from mission.flightlog import make_meta, write_flight_log
    from mission.localize.api import localize_log

    with tempfile.TemporaryDirectory() as d:
        cols = fl.log_columns(spec.field.origin)
        reps = int(np.ceil(args.samples / len(cols["t_s"])))
        cols = {k: np.tile(v, reps)[: args.samples] for k, v in cols.items()}
        cols["t_s"] = np.arange(args.samples) * 0.03
        p = write_flight_log(Path(d) / "bench.csv", cols, make_meta(spec.field.origin, {"kind": "sim"}))
        localize_log(p, method="onnx", model_path=args.model)
        tl = []
        for _ in range(3):
            t = time.perf_counter()
            localize_log(p, method="onnx", model_path=args.model)
            tl.append(time.perf_counter() - t)
        # the real-log default (fusion = selfcal + network) and selfcal alone, on the same flight read as a
        # real receiver's log (AFAR rover area as the search area), after one warm-up run each
        real = write_flight_log(Path(d) / "real.csv", cols, make_meta(spec.field.origin, {"kind": "real"}))
        tm: dict[str, list[float]] = {"fusion": [], "selfcal": []}
        for m in tm:
            localize_log(real, method=m)
            for _ in range(3):
                t = time.perf_counter()
                localize_log(real, method=m)
                tm[m].append(time.perf_counter() - t)
    print(
        f"full localize_log (CSV read + cruise + features + session load + inference): "
        f"median {1e3 * statistics.median(tl):.0f} ms"
    )
    for m, v in tm.items():
        print(f"full localize_log --method {m} (real-log path{', the default' if m == 'fusion' else ''}): "
              f"median {1e3 * statistics.median(v):.0f} ms over {len(v)} runs; target < 1000 ms")


if __name__ == "__main__":
    main()
