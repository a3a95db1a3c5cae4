"""The judge's threshold recalibrated on the vehicles real autopilots fly, by a rule written before
scoring (issue 33 item 1).

Why: where a network answered the survey, an adaptive flight's answer is the candidate the networks'
physics explains best when the smaller residual is at most ``rounds_answer.PHYSICS_RMS_DB`` (9.89
dB), else the rounds' choice. The threshold is the 95th percentile of that smaller residual on 40
flights under the mission's own physics (seed 5001), flown by the fast simulator's nearly level
vehicle. On ArduCopter SITL (cruise -14 deg) the candidates lie farther from the truth, and the
judge missed flights where the physics still told the candidates apart: seeds 8, 10 and 13 of this
stop (smaller residual 10.0-13.2 dB), where the rounds then chose the candidate the physics
explained worst (81, 55 and 43 m off, against 36, 17 and 31 m for the best explained).

Rule (written 2026-11-28 20:42 UTC, before any residual of the calibration flights below was
computed and before any flight was answered with another threshold):
- Calibration (fixes T'): ``bench_adaptive.py --flights 40 --jobs 2 --family mission --seed 5002
  --vehicle drag_pitch_deg_per_mps=K --json D/judge_K.json`` for K = 2.8 and 5.6 (cruise -15 and
  -28 deg, as ArduCopter and PX4 SITL fly). T' is the 95th percentile of the smaller residual
  (``physics_rms_db``) over those 80 flights, as T was over seed 5001. If T' <= T, nothing changes.
- The change: ``PHYSICS_RMS_DB`` = T'. The regions' masses stay as calibrated (their strata follow
  the judge's verdict with the new threshold).
- Adopted if all hold:
  1. every adaptive SITL flight on disk (stops 48-50, ArduCopter and PX4), answered after landing
     with T and with T' (the flight held fixed): the paired mean difference (T' - T) is below zero;
  2. the fast simulator's fresh flights of this stop (seeds 2045-2048, 160 per setting; the answer
     with T' computed from the rows' residuals and member errors): the mean change is at most
     +0.5 m under ``mission`` and at most +1 m under the ``afar`` family;
  3. the adaptive regions' held-out coverage (seeds 2047-2048, ``score_adaptive_regions.py``'s
     conditions 1 and 2) still holds with the strata of T'.
Reported beside: the same on each autopilot, and how often the judge fires with T and T'.

Result (2026-11-28): T' = 12.06 dB (80 flights; smaller residual median 7.02 dB). Adopted.
1. SITL, 91 adaptive flights: T' - T -1.0 [-2.0, -0.2] m (ArduCopter 51: -1.3 [-2.8, -0.2];
   PX4 40: -0.7 [-2.0, 0.0]); the judge fires on 81 instead of 71.
2. Fast simulator, 160 flights per setting: ``mission`` 8.3 -> 7.6 m (-0.71), ``afar`` 60.9 ->
   60.1 m (-0.75); 5 flights changed in each.
3. Regions held out with the new strata: ``afar`` 33 / 80 and 73 / 80, ``mission`` 31 / 80 and
   68 / 80 (worst 11.2 points; 7.5 with the old strata, today's masses 30.0).

Re-scored at the mission's sample period (rule written 2026-11-29 08:18 UTC, while the first
calibration run below was flying and before any of its residuals was read). Every figure above came
from fast-simulator flights sampled every 0.1 s (``bench_adaptive.py``'s default until c2077a9),
which handicapped the networks' answers (docs/adaptive.md, "The benchmark's sample period"); the
judge's residual is the networks' physics at their candidates, so T' may be an artefact of it.
- The same rule, run again with today's T' = 12.06 dB as the incumbent (``--incumbent 12.06``):
  the calibration flights flown again at the mission's period (same seed 5002, K = 2.8 and 5.6,
  40 flights each); T'' their 95th percentile. If T'' <= 12.06, nothing changes (the rule raises
  the threshold only: a lower one would hand flights to the rounds' choice, which the first rule
  found worse on the SITLs).
- Else conditions 1-3 with T'' against T': 1 on every adaptive SITL flight on disk; 2 on fresh
  fast-simulator flights at the mission's period (seed 2052, 40 per setting, ``mission`` and
  ``afar``: a quarter of the first rule's 160, for the time); 3 on the same rows.
Result (2026-11-29): T'' = 9.26 dB (80 flights; smaller residual median 5.26 dB, against 7.02 at
0.1 s): nothing changes. Sampled at the mission's period the networks' candidates lie nearer the
truth and the physics explains them better, so the 95th percentile falls back near the first
threshold (9.89 dB, a level vehicle at 0.1 s). The threshold stays 12.06 dB on the first rule's
condition 1, which was measured on SITL logs sampled at the mission's period (T' - T -1.0 [-2.0,
-0.2] m over 91 flights), not on the fast simulator. The calibration flights' table: fixed 7.9
[6.6, 9.3] / adaptive 7.3 [4.9, 10.3] m at -15 deg, 8.4 [6.5, 10.7] / 7.5 [5.8, 9.4] m at -28 deg.

    python benchmarks/score_judge_threshold.py calibrate D/judge_2.8.json D/judge_5.6.json
    python benchmarks/score_judge_threshold.py score --threshold T' --sitl S/flights.jsonl ... \\
        --bench D/test_*.json D/cal_*.json --regions D/test_*.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import mission.localize.rounds_answer as ra  # noqa: E402
from mission.evidence import paired_difference  # noqa: E402

TODAY = 9.89  # T, the threshold the rule replaced (rounds_answer.PHYSICS_RMS_DB before it)
NEW = "T'"


def calibrate(paths: list[Path], today: float = TODAY) -> float:
    """T': the 95th percentile of the smaller residual over the calibration rows; ``today``: the
    incumbent threshold."""
    m = [
        min(r["adaptive"]["physics_rms_db"])
        for p in paths
        for r in json.loads(p.read_text())
        if r["adaptive"].get("physics_rms_db")
    ]
    t = float(np.percentile(m, 95))
    print(f"{len(m)} flights; smaller residual median {np.median(m):.2f} dB; T' = {t:.2f} dB")
    print(f"today's T = {today:.2f} dB: {'change' if t > today else 'nothing changes'}")
    return t


def sitl_answers(stores: list[Path], thresholds: dict[str, float]) -> list[dict]:
    """Each adaptive SITL log on disk answered with each threshold."""
    from bench_sitl_seeds import stored_flights  # noqa: PLC0415

    from mission.localize.api import localize_log  # noqa: PLC0415

    rows, product = [], ra.PHYSICS_RMS_DB
    for r, log in stored_flights(stores, "adaptive"):
        row = {"autopilot": r["autopilot"], "seed": r["seed"]}
        for name, t in thresholds.items():
            ra.PHYSICS_RMS_DB = t
            est = localize_log(log)
            row[name] = est.error_m
            rms = est.extras.get("physics_rms_db")
            row[f"{name}_judged"] = bool(rms) and min(rms) <= t
        ra.PHYSICS_RMS_DB = product
        rows.append(row)
    return rows


def bench_change(paths: list[Path], t_new: float) -> dict[str, list[tuple[float, float]]]:
    """Setting -> [(error with T, error with T')] from bench rows: the judge's pick recomputed from
    the rows' residuals and member errors (the same order: live, survey default, survey network)."""
    out: dict[str, list[tuple[float, float]]] = {}
    for p in paths:
        setting = "afar" if "afar" in p.stem else "mission"
        for r in json.loads(p.read_text()):
            a = r["adaptive"]
            rms, members = a.get("physics_rms_db"), list(a["member_errors_m"].values())
            now = a["error_m"]
            new = now
            if rms and min(rms) > TODAY and min(rms) <= t_new:
                new = members[int(np.argmin(rms))]
            out.setdefault(setting, []).append((now, new))
    return out


def score(args) -> bool:
    t_new = args.threshold
    rows = sitl_answers(args.sitl, {"T": TODAY, NEW: t_new})
    ok = True
    for ap in sorted({r["autopilot"] for r in rows}) + ["all"]:
        rs = [r for r in rows if ap in ("all", r["autopilot"])]
        d = paired_difference([r[NEW] for r in rs], [r["T"] for r in rs])
        fired = (sum(r["T_judged"] for r in rs), sum(r[NEW + "_judged"] for r in rs))
        old_m, new_m = np.mean([r["T"] for r in rs]), np.mean([r[NEW] for r in rs])
        print(
            f"SITL {ap:9s} ({len(rs)}): T {old_m:.1f} m, T' {new_m:.1f} m, T' - T {d.fmt()} m; "
            f"judge fires {fired[0]} -> {fired[1]}"
        )
        if ap == "all":
            ok = d.value < 0.0
            print(f"condition 1: {ok}")
    for setting, pairs in sorted(bench_change(args.bench, t_new).items()):
        now, new = np.array(pairs).T
        d = float(np.mean(new - now))
        lim = 0.5 if setting == "mission" else 1.0
        print(
            f"bench {setting} ({len(pairs)}): {now.mean():.1f} -> {new.mean():.1f} m "
            f"({d:+.2f} m; at most {lim:+.1f}); flights changed {int(np.sum(new != now))}"
        )
        ok = ok and d <= lim
    # condition 3: the shipped masses, the strata of T'
    import score_adaptive_regions as sar  # noqa: PLC0415

    # the masses shipped when this rule was scored (the first rule's)
    c3 = sar.score(args.regions, "B", sar.B_MASS, judge_db=t_new)
    print(f"condition 3: {c3}")
    ok = ok and c3
    print(f"-> {'adopted' if ok else 'not adopted'}")
    return ok


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("calibrate")
    c.add_argument("files", nargs="+", type=Path)
    c.add_argument("--incumbent", type=float, default=TODAY, help="today's threshold, dB")
    s = sub.add_parser("score")
    s.add_argument("--threshold", type=float, required=True)
    s.add_argument("--sitl", nargs="+", type=Path, required=True)
    s.add_argument("--bench", nargs="+", type=Path, required=True)
    s.add_argument("--regions", nargs="+", type=Path, required=True, help="held-out bench rows")
    a = p.parse_args(argv)
    if a.cmd == "calibrate":
        calibrate(a.files, a.incumbent)
    else:
        score(a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
