"""Issue 33 against what the user sees: every stored SITL pair answered again by today's
``localize``.

Why: each stop changes what ``localize`` answers on an adaptive or a fixed log (a network adopted,
a threshold moved), so the SITL flights of earlier stops are answered again with the code of now.
Each log is answered as a user's ``localize LOG`` would (``localize_log`` with no method: the
product's default for that log); a seed flown more than once counts as the mean of its flights;
90 % bootstrap intervals over seeds.

    python benchmarks/sitl_user_sees.py STORE/flights.jsonl [...] --workers 2 [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sitl_seeds import seed_means, stored_rows  # noqa: E402

from mission.evidence import mean_interval, paired_difference  # noqa: E402
from mission.threads import limit_worker  # noqa: E402


def pairs(stores: list[Path]) -> list[dict]:
    """The stored flights (``rc`` 0, log on disk, each log once) of seeds flown on both arms."""
    rows = [
        {k: r[k] for k in ("autopilot", "seed", "arm", "log")}
        for r in stored_rows(stores)
        if r.get("rc") == 0
    ]
    arms = defaultdict(set)
    for r in rows:
        arms[(r["autopilot"], r["seed"])].add(r["arm"])
    return [r for r in rows if arms[(r["autopilot"], r["seed"])] >= {"fixed", "adaptive"}]


def _answer(row: dict) -> dict:
    from mission.localize.api import localize_log  # noqa: PLC0415

    est = localize_log(row["log"])
    return {**row, "error_m": est.error_m, "method": est.method}


def table(rows: list[dict]) -> list[str]:
    """Two lines of at most 80 columns per autopilot: seeds, each arm's mean, the paired
    difference and the seeds on which the adaptive answer is no worse."""
    out = []
    for ap in sorted({r["autopilot"] for r in rows}):
        mine = [r for r in rows if r["autopilot"] == ap]
        seeds, f, a = seed_means(mine, lambda r: r["error_m"])
        ok = sum(x <= y for x, y in zip(a, f, strict=True))
        out += [
            f"{ap}: {len(seeds)} seeds; fixed {mean_interval(f).fmt()} m, adaptive "
            f"{mean_interval(a).fmt()} m;",
            f"  adaptive - fixed {paired_difference(a, f).fmt()} m; no worse on {ok} of "
            f"{len(seeds)}",
        ]
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("stores", nargs="+", type=Path, help="bench_sitl_seeds.py flights.jsonl files")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--json", type=Path, help="write each log's answer")
    a = p.parse_args(argv)
    jobs = pairs(a.stores)
    with ProcessPoolExecutor(a.workers, initializer=limit_worker) as ex:
        rows = list(ex.map(_answer, jobs))
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"{len(rows)} logs answered by today's localize")
    for line in table(rows):
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
