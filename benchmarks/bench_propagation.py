"""Propagation throughput on one core: e2r with the dipole and the measured pattern.

Run: ``python benchmarks/bench_propagation.py`` (prints a table; ``--quick`` for a short run).
Cases: one flight (1 transmitter x 20 000 samples) and a batch (1 000 transmitters x 10 000 samples,
the shape of a localizer grid search or dataset generation).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_v] = "1"  # one core: set before numpy is imported

import argparse  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402

from mission.defaults import DEFAULT_TX_HEIGHT_M  # noqa: E402
from mission.physics import make_model  # noqa: E402


def _flight(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A spiral at 30 m with +-5 deg roll/pitch and yaw along the track."""
    t = np.linspace(0, 1, n)
    r = 20 + 180 * t
    th = 12 * np.pi * t
    rx = np.c_[200 + r * np.cos(th), 200 + r * np.sin(th), np.full(n, 30.0)]
    att = np.c_[rng.uniform(-0.087, 0.087, (n, 2)), np.mod(np.pi / 2 - th, 2 * np.pi)]
    return rx, att


def _time(fn, repeat: int) -> tuple[float, float]:
    """Best wall time and best CPU time (process_time: robust when other processes share the
    core)."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick", action="store_true", help="100 transmitters in the batch instead of 1 000"
    )
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    m_tx = 100 if args.quick else 1000
    rows = []
    for pattern in ("dipole", "measured"):
        model = make_model("e2r", pattern=pattern)
        for label, n_tx, n in (("flight", 1, 20_000), ("batch", m_tx, 10_000)):
            rx, att = _flight(n, rng)
            tx = np.c_[rng.uniform(0, 400, (n_tx, 2)), np.full(n_tx, DEFAULT_TX_HEIGHT_M)][
                :, None, :
            ]
            if pattern == "measured" and label == "batch":
                tx = tx[: max(1, n_tx // 10)]  # 10x fewer: the tabulated path is slower
            model.rss_dbm(tx[:1], rx[:1000], att[:1000])  # warm up
            args_ = (tx, rx, att)
            sec, cpu = _time(lambda m=model, a=args_: m.rss_dbm(*a), 5 if label == "flight" else 3)
            tracemalloc.start()
            model.rss_dbm(tx, rx, att)
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            n_s = tx.shape[0] * n
            rows.append(
                (
                    f"e2r {pattern}",
                    label,
                    f"{tx.shape[0]} x {n}",
                    n_s / sec / 1e6,
                    n_s / cpu / 1e6,
                    sec * 1e3,
                    peak / 2**20,
                )
            )
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"{'model':<14} {'case':<7} {'tx x samples':>14} {'M/s wall':>9} {'M/s cpu':>8} "
        f"{'wall ms':>9} "
        f"{'peak MiB':>9}"
    )
    for name, case, shape, rate, rate_cpu, ms, mib in rows:
        print(
            f"{name:<14} {case:<7} {shape:>14} {rate:>9.2f} {rate_cpu:>8.2f} {ms:>9.1f} {mib:>9.1f}"
        )
    print(f"process max RSS {maxrss:.0f} MiB; numpy {np.__version__}; one thread")


if __name__ == "__main__":
    main()
