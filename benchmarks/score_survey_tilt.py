"""The survey network trained on nose-down cruise, for adaptive flights flown tilted: a rule written
before the network was trained or any flight was answered with it.

Why: once the fixed spiral on the SITLs is answered by the tilt network (``score_tilt_network.py``,
adopted), the fixed mission errs 7.9 m on ArduCopter SITL and 9.1 m on PX4 SITL. The adaptive
answer errs 9.4 and 16.3 m on the same transmitters: PX4's adaptive mission is now worse than its
fixed one, paired +7.2 [1.1, 14.1] m. The adaptive answer's judge weighs three candidates: the live
method, the fixed default on the survey (now the tilt spiral network, trained on whole spirals) and
the survey network ``rfsl_survey_e2r``, trained on level surveys only. On the SITL logs that third
candidate erred 4-124 m.

Rule (written 2026-11-28 22:33 UTC; the network is not trained and no flight has been answered with
it):

- Candidate ``rfsl_survey_tilt.onnx``: ``rfsl_survey_e2r``'s recipe (the spiral recipe on the survey
  of ``missions/spiral_adaptive.yaml``) on 16 000 surveys with the nose-down pitch drawn per flight
  (``rfsl dataset missions/spiral_adaptive.yaml --seed 71 --drag-pitch 0.6,6``), seed 0.
- Change (``rounds_answer.survey_network``): where the survey's flown roll or pitch (5-95 %)
  leaves ``rfsl_survey_e2r``'s training span (no tolerance) and lies inside the candidate's, the
  candidate is the judge's third candidate. Everything else is as today: the live method, the
  fixed default, the judge and its threshold, the regions' masses.
- Evidence, each flight answered both ways (the flights held fixed; "today" is the shipped code,
  the tilt spiral network included, with this network absent):
  - A: every adaptive SITL log on disk (``bench_sitl_seeds.py`` stores, both autopilots), paired
    change - today per log, 90 % cluster bootstrap over transmitters (the seed), 4 000 replicates,
    seed 0.
  - B: the fast simulator flown nose down, ``bench_adaptive.py --family mission --vehicle
    drag_pitch_deg_per_mps=K --flights 40 --seed 5003`` for K = 2.8 and 5.6, run with and without
    the network file. The planner never reads the survey network, so both runs fly the same
    flights; this is checked (the fixed arm's errors and the rounds are identical).
  - C: the same with the level vehicle (no ``--vehicle``), seed 5003.
- Adopted if all hold:
  1. A, both autopilots pooled: the upper end of the interval is below zero;
  2. A, each autopilot alone: the lower end is below zero;
  3. B: on each setting the adaptive arm's mean moves by at most +0.5 m;
  4. C: no level flight's answer moves.
- Reported beside, deciding nothing: issue 33's comparison on the SITLs (adaptive - fixed per
  transmitter, both as ``localize`` answers them now); the regions' coverage on the adaptive SITL
  logs.

Result of this rule (2026-11-28 22:59 UTC): NOT ADOPTED. Condition 3 failed on its own check, not on
the errors.
- Trained in 364 s (136 epochs; validation 5.4 m mean over the range).
- A (91 adaptive SITL logs, 25 transmitters, all routed): 13.3 -> 6.3 m, paired -7.0 [-10.4, -3.7]
  m (1 holds); ArduCopter -5.8 [-9.2, -2.6], PX4 -8.5 [-13.0, -4.6] (2 holds).
- B: at 2.8 deg per m/s, 40/40 flights identical, 13.0 -> 11.1 m, -1.9 [-4.2, 0.6]; at 5.6, 39/40
  identical, 14.3 -> 11.2 m, -3.1 [-5.6, -0.7]. Flight 34 at 5.6 flew 3 rounds instead of 4, its
  third elsewhere. The premise was wrong: once rounds exist, the live series carries the rounds
  answer, and the planner reads its point and candidates (``rounds.py``: target and rival), so the
  survey network reaches later rounds. Condition 3 required identical flights: False.
- C (level, seed 5003): 40/40 identical, 0 answers moved (4 holds).
- Beside: issue 33 on the SITL logs, adaptive - fixed: ArduCopter -3.5 [-5.1, -2.1] m (4.4 against
  7.9 m), PX4 -0.6 [-4.3, 3.9] m (8.4 against 9.1 m). The regions held 46/91 and 90/91 both ways.

Second rule (written 2026-11-28 22:59 UTC, before any of its flights was flown or answered), on
fresh evidence with the premise corrected: the change is the network in the judge during and after
the flight, so the flights are paired by world (seed), not held fixed.
- A2: fresh SITL flights flown with the change (``bench_sitl_seeds.py --arms adaptive fixed``):
  ArduCopter 20x seeds 25-34, PX4 10x seeds 20-24. Each adaptive log is answered with the network
  and without it (the log held fixed), paired per log, cluster bootstrap by seed.
- B2: ``bench_adaptive.py --family mission --flights 40 --seed 5004`` at 2.8 and 5.6 deg per m/s,
  with and without the network file, paired by world (flight index).
- Adopted if all hold:
  1. A2, both autopilots pooled: the paired mean is below zero and the upper end of its interval
     is below +0.5 m;
  2. A2, each autopilot: the lower end of its interval is below zero;
  3. B2, each setting: the paired mean moves by at most +0.5 m;
  4. C as measured above (level flights never move).
- Beside: issue 33 on the fresh seeds (adaptive - fixed, both arms flown with the change).

Result of the second rule (2026-11-28 23:33 UTC): NOT ADOPTED (condition 3 fails). The network is
not shipped; ``rounds_answer`` keeps the routing for it, so this file reproduces both rules once it
is trained into ``models/``.
- A2, 15 fresh SITL flights (every one exit 0): 7.2 -> 5.7 m, paired -1.5 [-3.5, 0.1] m (1 holds);
  ArduCopter 10: 6.0 -> 4.1 m, -1.9 [-4.9, 0.4]; PX4 5: 9.5 -> 8.9 m, -0.6 [-1.8, 0.0] (2 holds).
- B2, seed 5004: at 2.8 deg per m/s, 11.1 -> 12.2 m, +1.1 [-1.2, 4.0]; at 5.6, 12.6 -> 14.0 m,
  +1.4 [-0.9, 4.1] (38/40 and 40/40 flights identical). Condition 3 fails on both.
- Both rules together: on the SITL logs it helps (-7.0 m on 91 logs, -1.5 m on 15 fresh ones); on
  the fast simulator flown nose down it moves the adaptive answer by -1.9 / -3.1 m on seed 5003
  and +1.1 / +1.4 m on seed 5004, i.e. by noise.

Third rule (written 2026-11-29 08:24 UTC, before any flight below was flown or any log answered
with the network this stop). Both rules' fast-simulator evidence (B, B2) was flown with RSS
sampled every 0.1 s, ``bench_adaptive.py``'s default until c2077a9, which handicaps the networks
(trained at the mission's 0.03 s: docs/adaptive.md, "The benchmark's sample period"). Condition 3
failed on that evidence alone. The network is the one trained for the first rule (sha256
e29028bc...), not retrained.
- A3: every adaptive SITL log flown since the second rule, none of them seen by either rule
  (stop 52: PX4 10x seeds 25-34; stop 53: ArduCopter 20x and PX4 10x seeds 0-2, ArduCopter windy
  seeds 40-43, 53, 54; stop 54: ArduCopter seeds 55-66, PX4 seeds 35-46), each answered with and
  without the network (the log held fixed), paired per log, cluster bootstrap by seed.
- B3: ``bench_adaptive.py --family mission --flights 40 --seed 5005`` at the mission's period
  (its default now), at 2.8 and 5.6 deg per m/s, with and without the network file, paired by world.
- C3: the same, level (no ``--vehicle``), seed 5005.
- Adopted (the network ships in ``models/`` with its card) if all hold:
  1. A3, both autopilots pooled: the paired mean is below zero and the upper end of its interval
     is below +0.5 m (the second rule's condition 1);
  2. A3, each autopilot: the lower end of its interval is below zero;
  3. B3, each setting: the paired mean moves by at most +0.5 m;
  4. C3: no level flight's answer moves.
- Beside: issue 33 on the A3 seeds (adaptive - fixed, both answered by ``localize`` with the
  change).

Result of the third rule (2026-11-29 08:37 UTC): ADOPTED; ``models/rfsl_survey_tilt.onnx`` ships.
- A3, 44 adaptive SITL logs (39 transmitters; routed to the network on 39): 9.3 -> 5.7 m, paired
  -3.5 [-5.9, -1.5] m (1 holds); ArduCopter 19: 10.5 -> 6.6 m, -4.0 [-7.5, -1.1]; PX4 25: 8.3 ->
  5.1 m, -3.2 [-6.9, -0.8] (2 holds).
- B3, seed 5005 at the mission's period, 40/40 flights identical with and without: at 2.8 deg per
  m/s 10.2 -> 8.3 m, -1.8 [-3.7, -0.1]; at 5.6, 12.0 -> 8.9 m, -3.1 [-5.4, -1.0] (3 holds). The
  same kind of flights sampled every 0.1 s had moved by +1.1 / +1.4 m (seed 5004).
- C3, level: 0 of 40 answers moved (4 holds).
- Beside, issue 33 with the change (each seed's logs averaged): ArduCopter 17 transmitters, fixed
  11.2 m, adaptive 6.2 m, -5.1 [-12.2, +0.3] m (6 worse); PX4 25, fixed 9.0 m, adaptive 5.1 m, -3.9
  [-7.0, -0.9] m (6 worse). The regions held 18/44 and 43/44 with and without it.
- Beside: the ``afar`` family at 2.8 deg per m/s, seed 5005: 0 of 40 answers moved.
- Reproduce: the network from ``/tmp/s51`` (the first rule's training, now in ``models/``), then
  ``score_survey_tilt.py sitl`` on the seven stores named in A3 and ``bench`` (``--paired-by-world``
  for B3, ``--level`` for C3) on the six ``bench_adaptive.py`` runs, each run from a checkout with
  and one without ``models/rfsl_survey_tilt.onnx``.

    python benchmarks/score_survey_tilt.py sitl STORE2/flights.jsonl --json A2.json
    python benchmarks/score_survey_tilt.py bench --paired-by-world B2_28_with.json \\
        B2_28_without.json B2_56_with.json B2_56_without.json

    rfsl dataset missions/spiral_adaptive.yaml --n 16000 --features clustering --seed 71 \\
        --drag-pitch 0.6,6 --out DS/survey_tilt
    rfsl train DS/survey_tilt --epochs 140 --patience 30 --batch-size 256 --lr 3e-3 --seed 0 \\
        --threads 2 --no-augment --coords relative --out models/rfsl_survey_tilt.onnx
    python benchmarks/score_survey_tilt.py sitl STORE/flights.jsonl [...] --json A.json
    # B and C: each setting run twice, the second time with the network moved away
    python benchmarks/bench_adaptive.py --family mission --vehicle drag_pitch_deg_per_mps=2.8 \\
        --flights 40 --seed 5003 --json B28_with.json
    python benchmarks/score_survey_tilt.py bench B28_with.json B28_without.json [...]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sitl_seeds import seed_means  # noqa: E402
from score_tilt_network import answer, answer_stored, paired, summary, without  # noqa: E402

import mission.localize.rounds_answer as rounds_answer  # noqa: E402
from mission.evidence import paired_difference  # noqa: E402
from mission.flightlog import read_flight_log  # noqa: E402
from mission.shipped import shipped_model  # noqa: E402

TILT = rounds_answer.SURVEY_TILT_NETWORK


def _sitl_one(job: tuple[dict, str]) -> dict:
    r, path = job
    log = read_flight_log(path)
    with without(rounds_answer, "SURVEY_TILT_NETWORK"):
        before = answer(log)
    return {
        "autopilot": r["autopilot"],
        "seed": r["seed"],
        "arm": r["arm"],
        "log": path,
        "today": before,
        "change": answer(log),
    }


def _issue33(rows: list[dict]) -> None:
    """Beside: adaptive - fixed per transmitter (each arm's logs of a seed averaged), as
    ``localize`` answers both with the change."""
    for ap in sorted({r["autopilot"] for r in rows}):
        mine = [r for r in rows if r["autopilot"] == ap]
        seeds, f, a = seed_means(mine, lambda r: r["change"]["error_m"])
        d = paired_difference(a, f)
        worse = sum(x > y for x, y in zip(a, f, strict=True))
        print(
            f"beside, issue 33, {ap}: {len(seeds)} transmitters, fixed {np.mean(f):.1f} m, "
            f"adaptive {np.mean(a):.1f} m, adaptive - fixed {d.fmt()} m ({worse} worse)"
        )


def sitl(stores: list[Path], workers: int, out: Path | None) -> bool:
    """Conditions 1-2 on the adaptive logs; issue 33's comparison and the regions beside."""
    rows = answer_stored(stores, ("adaptive", "fixed"), _sitl_one, workers, out)
    ad = [r for r in rows if r["arm"] == "adaptive"]
    summary(ad, "adaptive, both autopilots", TILT)
    d = paired(ad)
    ok = d.hi < 0
    print(f"condition 1 (first rule): {ok}")
    print(f"condition 1 (second rule): {d.value < 0 and d.hi < 0.5}")
    for ap in sorted({r["autopilot"] for r in ad}):
        sub = [r for r in ad if r["autopilot"] == ap]
        summary(sub, f"adaptive, {ap}", TILT)
        ok2 = paired(sub).lo < 0
        print(f"condition 2, {ap}: {ok2}")
        ok = ok and ok2
    _issue33(rows)
    for v in ("today", "change"):
        n = len(ad)
        c50 = sum(r[v]["cov50"] for r in ad)
        c90 = sum(r[v]["cov90"] for r in ad)
        print(f"beside, adaptive regions, {v}: 50 % holds {c50}/{n}, 90 % {c90}/{n}")
    return ok


def _bench(path: Path) -> list[dict]:
    return json.loads(path.read_text())


def bench(pairs: list[tuple[Path, Path]], level: bool, by_world: bool = False) -> bool:
    """Condition 3 (nose-down settings) or 4 (``level``): with / without runs of bench_adaptive,
    the same flights."""
    ok = True
    for with_p, without_p in pairs:
        a, b = _bench(with_p), _bench(without_p)
        same = [
            x["fixed"]["error_m"] == y["fixed"]["error_m"]
            and x["adaptive"]["rounds"] == y["adaptive"]["rounds"]
            for x, y in zip(a, b, strict=True)
        ]
        ea = [x["adaptive"]["error_m"] for x in a]
        eb = [y["adaptive"]["error_m"] for y in b]
        d = paired_difference(ea, eb)
        moved = sum(abs(x - y) > 1e-9 for x, y in zip(ea, eb, strict=True))
        print(
            f"{with_p.name}: same flights {sum(same)}/{len(same)}; adaptive {np.mean(ea):.1f} m "
            f"with, {np.mean(eb):.1f} m without, paired {d.fmt()} m; {moved} answers moved"
        )
        held = all(same) or by_world  # the second rule pairs by world: flights may differ
        ok = ok and held and (moved == 0 if level else d.value <= 0.5)
    print(f"condition {4 if level else 3}: {ok}")
    return ok


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    st = sub.add_parser("sitl")
    st.add_argument("stores", nargs="+", type=Path)
    st.add_argument("--workers", type=int, default=2)
    st.add_argument("--json", type=Path)
    b = sub.add_parser("bench", help="WITH WITHOUT [WITH WITHOUT ...] bench_adaptive JSONs")
    b.add_argument("files", nargs="+", type=Path)
    b.add_argument("--level", action="store_true", help="condition 4: no answer may move")
    b.add_argument(
        "--paired-by-world",
        action="store_true",
        help="the second rule: pair by world, flights may differ",
    )
    a = p.parse_args(argv)
    if a.cmd == "sitl":
        if shipped_model(TILT) is None:
            print(f"models/{TILT} is missing: train it first (this file's docstring)")
            return 2
        sitl(a.stores, a.workers, a.json)
    else:
        if len(a.files) % 2:
            print("bench takes pairs: WITH WITHOUT")
            return 2
        bench(list(zip(a.files[::2], a.files[1::2], strict=True)), a.level, a.paired_by_world)
    return 0


if __name__ == "__main__":
    sys.exit(main())
