"""Shared by the rule-scoring benchmarks (point_estimates, rover_hypotheses, fusion_network): their
command line and the loading of one scored flight, a benchmark flight or an imported real log, with
its truth."""

from __future__ import annotations

import argparse
import contextlib
import tempfile
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from mission.flightlog import read_flight_log
from mission.threads import limit_worker
from mission.workshop.evaluate import import_afar
from mission.workshop.suite_cache import read_suite


def scoring_parser(doc: str | None) -> argparse.ArgumentParser:
    """--suite-dir (the benchmark cache), --n, --mat (the AFAR 2023 .mat folder), --workers."""
    ap = argparse.ArgumentParser(description=(doc or "").split("\n")[0])
    ap.add_argument("--suite-dir", required=True, help="rfsl dataset --suite unseen --logs cache")
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--mat", required=True, help="folder of the AFAR 2023 .mat files")
    ap.add_argument("--workers", type=int, default=2)
    return ap


def flight_with_truth(kind: str, src: str, i: int):
    """(FlightLog, truth xy in its ENU frame) of benchmark flight ``i`` of the cache ``src`` (kind
    "suite") or of the imported real log at ``src`` (kind "real", truth from its sidecar)."""
    if kind == "suite":
        fl = read_suite(src).load(i)
        return fl.log, np.asarray(fl.truth_xy)
    log = read_flight_log(src)
    return log, np.asarray(log.truth_enu[:2])


@contextlib.contextmanager
def real_logs_and_pool(args) -> Iterator[tuple[list[Path], ProcessPoolExecutor]]:
    """(the six AFAR flights of ``args.mat`` imported into a temporary folder, sorted; a pool of
    ``args.workers`` worker processes, each limited to one thread), both gone on exit."""
    with (
        tempfile.TemporaryDirectory() as tmp,
        ProcessPoolExecutor(args.workers, initializer=limit_worker) as ex,
    ):
        yield sorted(import_afar(args.mat, tmp)), ex
