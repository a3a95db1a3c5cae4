"""The fixed spiral against the adaptive mission on real autopilots in SITL, seed by seed.

    # ArduCopter at 20x and PX4 at 10x, seeds 0-4, both missions: about 35 min on 2 cores
    python benchmarks/bench_sitl_seeds.py --out /tmp/sitl_seeds
    # one autopilot, fewer seeds
    python benchmarks/bench_sitl_seeds.py --autopilot ardupilot --seeds 0 1 2

Each flight starts a fresh SITL from ``../shared/sitl/<autopilot>/start.sh`` (the missions' home
as its take-off point), flies ``fly-mission MISSION --seed N`` against it (the simulated transmitter
and RSS noise of seed N, the same for both missions) and scores what the user is shown after
landing: ``localize flight.csv --json``'s answer against the simulated truth (issue 33 item 4:
compare against what the fixed mission shows the user). Reported per autopilot: each seed's error
on both missions, the mean errors and the paired mean difference adaptive - fixed with its 90 %
bootstrap interval (``mission.evidence``), and each flight's arm-to-disarm time. Results are
appended, one JSON line per flight, to ``OUT/flights.jsonl``; a rerun skips flights already there,
so an interrupted run resumes.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mission.evidence import mean_interval, paired_difference
from mission.flightlog import read_flight_log
from mission.spec import load_mission
from sitl.shared import SharedSitl

ROOT = Path(__file__).resolve().parents[1]

SHARED = ROOT.parent / "shared" / "sitl"
MISSIONS = {
    "fixed": ROOT / "missions" / "spiral.yaml",
    "adaptive": ROOT / "missions" / "spiral_adaptive.yaml",
}
# autopilot -> (speed-up, text its log shows once it accepts a ground station,
# MAVSDK address of instance I)
AUTOPILOTS = {
    "ardupilot": (20, "", lambda i: f"tcpout://127.0.0.1:{5760 + 10 * i}"),
    "px4": (10, "Ready for takeoff!", lambda i: f"udpin://0.0.0.0:{14540 + i}"),
}


def start_sitl(
    autopilot: str, speedup: float, instance: int, run: Path, script: Path | None = None
) -> SharedSitl:
    """Start one SITL in ``run`` from the missions' home (by ``script``, default
    ``../shared/sitl/<autopilot>/start.sh``, which takes the same arguments) and wait until it
    accepts a ground station."""
    spec = load_mission(MISSIONS["fixed"])
    lat, lon, _ = spec.field.origin.to_geodetic(spec.home_enu)
    home = f"{lat:.7f},{lon:.7f},0" + (",0" if autopilot == "ardupilot" else "")
    sitl = SharedSitl(run, "px4.log" if autopilot == "px4" else "sitl.log")
    sitl.launch(
        script or SHARED / autopilot / "start.sh",
        [str(speedup), str(instance), home],
        AUTOPILOTS[autopilot][1],
        f"{autopilot} SITL",
    )
    return sitl


def fly_one(
    autopilot: str,
    arm: str,
    seed: int,
    out: Path,
    instance: int,
    speedup: float | None = None,
    script: Path | None = None,
) -> dict:
    """One flight of ``arm``'s mission with ``--seed seed`` against a fresh SITL (at ``speedup``,
    default the autopilot's in ``AUTOPILOTS``; started by ``script``, default the shared
    start.sh), scored by ``localize --json``."""
    default, _, url = AUTOPILOTS[autopilot]
    speedup = speedup or default
    folder = out / f"{autopilot}_{arm}_{seed}"
    sitl = start_sitl(autopilot, speedup, instance, folder / "sitl", script)
    t0 = time.monotonic()
    try:
        fly = subprocess.run(
            [
                sys.executable,
                "-m",
                "mission.cli.fly",
                str(MISSIONS[arm]),
                "--connect",
                url(instance),
            ]
            + ["--speedup", str(speedup), "--seed", str(seed), "--out", str(folder / "flights")]
            + ["--link-timeout", "60"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=900,
        )
    finally:
        sitl.stop()
    wall = time.monotonic() - t0
    (folder / "fly.out").write_text(fly.stdout + fly.stderr)
    logs = sorted((folder / "flights").glob("*/flight.csv"))
    row = {"autopilot": autopilot, "arm": arm, "seed": seed, "speedup": speedup}
    row |= {"rc": fly.returncode, "wall_s": wall}
    if not logs:
        return row | {"error_m": None}
    ans = subprocess.run(
        [sys.executable, "-m", "mission.cli.localize", str(logs[-1]), "--json"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    res = json.loads(ans.stdout) if ans.returncode == 0 else {}
    meta = read_flight_log(logs[-1]).meta
    ad = meta.get("adaptive") or {}
    return row | {
        "log": str(logs[-1]),
        "error_m": res.get("error_m"),
        "method": res.get("method"),
        "flight_s": (meta.get("budget") or {}).get("used_s"),
        "rounds": len(ad.get("rounds") or []),
        "live_final_error_m": (meta.get("final_estimate") or {}).get("error_m"),
        # issue 33 item 3: how old each round's data was when it began, and the series' gaps
        "data_lead_s": [rd.get("data_lead_s") for rd in ad.get("rounds") or []],
        "series_max_gap_s": series_max_gap(meta),
    }


def stored_rows(stores: list[Path]):
    """Each flight's row in bench stores (``OUT/flights.jsonl`` files) whose log is still on disk,
    each log once: for scorers that answer stored flights again."""
    seen = set()
    for store in stores:
        for line in Path(store).read_text().splitlines():
            r = json.loads(line)
            if not r.get("log") or r["log"] in seen:
                continue
            if Path(r["log"]).exists():
                seen.add(r["log"])
                yield r


def stored_flights(stores: list[Path], arm: str):
    """(row, log) of each stored flight of ``arm`` (``stored_rows``)."""
    for r in stored_rows(stores):
        if r["arm"] == arm:
            yield r, read_flight_log(r["log"])


def seed_means(rows: list[dict], error) -> tuple[list, list[float], list[float]]:
    """(seeds flown on both arms, the fixed arm's mean error per seed, the adaptive arm's) over
    ``rows`` (stored flights of one autopilot; ``error(row)`` its error, None skipped): a seed
    flown more than once counts as the mean of its flights."""
    by: dict = defaultdict(lambda: defaultdict(list))
    for r in rows:
        e = error(r)
        if e is not None:
            by[r["seed"]][r["arm"]].append(e)
    seeds = sorted(s for s in by if by[s]["fixed"] and by[s]["adaptive"])
    fixed = [float(np.mean(by[s]["fixed"])) for s in seeds]
    return seeds, fixed, [float(np.mean(by[s]["adaptive"])) for s in seeds]


def series_max_gap(meta: dict) -> float | None:
    """The longest gap (log s) of the live series between its first entry and the final one."""
    ts = [d["t_s"] for d in meta.get("estimates") or []]
    final = (meta.get("final_estimate") or {}).get("t_s")
    ts = [t for t in ts if final is None or t <= final]
    return round(max(b - a for a, b in zip(ts, ts[1:], strict=False)), 1) if len(ts) > 1 else None


def summarize(rows: list[dict], autopilot: str) -> list[str]:
    """The per-seed table and the paired figures of one autopilot, in lines of at most 80
    columns."""
    by = {(r["arm"], r["seed"]): r for r in rows if r["autopilot"] == autopilot}
    seeds = sorted({s for _, s in by if ("fixed", s) in by and ("adaptive", s) in by})
    ok = [
        s
        for s in seeds
        if by["fixed", s]["error_m"] is not None and by["adaptive", s]["error_m"] is not None
    ]
    lines = [f"{autopilot}: seed  fixed m  adaptive m  (method, rounds, flight s)"]
    for s in seeds:
        f, a = by["fixed", s], by["adaptive", s]
        fe = "-" if f["error_m"] is None else f"{f['error_m']:.1f}"
        ae = "-" if a["error_m"] is None else f"{a['error_m']:.1f}"
        lines.append(
            f"  {s:4d}  {fe:>7}  {ae:>10}  ({a.get('method')}, {a.get('rounds')}, "
            f"{f.get('flight_s')} / {a.get('flight_s')})"
        )
    if ok:
        fe = [by["fixed", s]["error_m"] for s in ok]
        ae = [by["adaptive", s]["error_m"] for s in ok]
        lines.append(
            f"  mean fixed {mean_interval(fe).fmt()} m, adaptive {mean_interval(ae).fmt()} m"
        )
        lines.append(f"  adaptive - fixed {paired_difference(ae, fe).fmt()} m ({len(ok)} seeds)")
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--autopilot", nargs="+", default=list(AUTOPILOTS), choices=list(AUTOPILOTS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    ap.add_argument("--out", type=Path, default=Path("/tmp/sitl_seeds"))
    ap.add_argument("--instance", type=int, default=3, help="SITL instance (ports) to use")
    ap.add_argument(
        "--speedup",
        type=float,
        help="speed-up of every SITL (default: ArduCopter 20, PX4 10); the rounds are planned "
        "lead_s vehicle seconds ahead at any speed-up, and a higher one makes the vehicle wait "
        "longer at a part's end for the next round",
    )
    ap.add_argument(
        "--arms", nargs="+", default=list(MISSIONS), choices=list(MISSIONS), help="missions to fly"
    )
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    store = args.out / "flights.jsonl"
    rows = [json.loads(x) for x in store.read_text().splitlines()] if store.exists() else []
    done = {(r["autopilot"], r["arm"], r["seed"]) for r in rows}
    for autopilot in args.autopilot:
        for seed in args.seeds:
            for arm in args.arms:
                if (autopilot, arm, seed) in done:
                    continue
                row = fly_one(autopilot, arm, seed, args.out, args.instance, args.speedup)
                print(json.dumps(row), flush=True)
                rows.append(row)
                with store.open("a") as fh:
                    fh.write(json.dumps(row) + "\n")
    for autopilot in args.autopilot:
        print("\n".join(summarize(rows, autopilot)))


if __name__ == "__main__":
    main()
