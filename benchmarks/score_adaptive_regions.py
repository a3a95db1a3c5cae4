"""The regions an adaptive flight prints, recalibrated on adaptive flights, by a rule written before
scoring (issue 33, and the house rule that every estimate carries an honest uncertainty).

Why: an adaptive flight's answer (``--method rounds``) prints the live method's regions, whose HPD
masses (``selfcal.CALIBRATED_MASS``, 0.339 / 0.870) were calibrated on fixed paths of the
benchmark. The rounds fly low over one or two spots; their dense cells make the tempered posterior
narrower than on a fixed path. Under the family fitted to the real flights, that 90 % region held
the truth on 26 to 30 of 40 simulated adaptive flights at every seed measured (seeds 2027, 2028,
2044: docs/adaptive.md), and under the mission's own physics on 39 or 40 of 40.

Each ``bench_adaptive.py --json`` row records, for the answer ``localize`` prints after landing, the
truth's HPD level in its posterior (``compare.shown_regions``: the smallest mass whose set holds the
truth). The set of mass M holds the truth exactly when the level is below M, so masses are
calibrated offline, as ``calibrate_regions.py`` does for fixed flights; the flights themselves do
not depend on them (the rounds are planned on the live estimate, whose masses do not change).

Rule (written 2026-11-28 19:40 UTC, before any adaptive flight's level was looked at):
- Calibration flights (development; variants may be looked at there): ``bench_adaptive.py
  --flights 40 --jobs 2 --seed S --family F --json D/cal_F_S.json`` for S = 2045, 2046 and F =
  ``afar`` (the family fitted to the real flights) and ``mission`` (what ``fly-mission`` simulates
  against a SITL): 80 flights per setting.
- Variants, each a pair of masses (50 %, 90 %) for an adaptive flight's answer:
  A. one pair, calibrated on the ``afar`` flights (the reality-fitted family, as every other mass
     of the project);
  B. two pairs, by what the flight's own data say: flights the networks' physics explains
     (``rounds_answer.PHYSICS_RMS_DB``: the judge fired) and flights it does not, each pair
     calibrated on that stratum's flights of both settings pooled.
  Each is scored on the calibration flights by 5-fold cross-fitting (fold = flight index mod 5,
  per file), by its worst |coverage - nominal| over the two settings and the two levels; the
  smaller wins (ties: A, the simpler).
- Held out (scored once): seeds 2047 and 2048, both settings, 80 flights per setting, flown with the
  chosen masses in place (the flights are the same as with today's; today's coverage is read from
  the same levels).
- Adopted if all hold on the held-out flights:
  1. under ``afar``, the 90 % Clopper-Pearson interval of the 90 % region's coverage holds 0.90 and
     that of the 50 % region's holds 0.50;
  2. under ``mission``, the 90 % region's interval reaches 0.90 (it does not under-cover);
  3. the chosen masses' worst |coverage - nominal| over the settings and levels is below today's.
  Otherwise today's regions stay and the figures are reported.
Reported beside: the median 90 % area of each setting with today's and the chosen masses (today's
from the live estimate's ``area_m2``, the same posterior and masses), and how often the printed
point lies inside its own 90 % region.

Second rule, the judged masses on nose-down vehicles (written 2026-11-28 21:28 UTC, after the
judge's threshold moved to 12.06 dB and before any flight below was scored). On the 91 SITL
flights on disk the 50 % region held 22 / 51 on ArduCopter and 7 / 40 on PX4: the judged masses
were fitted where judged answers lay near the truth (a level vehicle), and on nose-down autopilots
they do not as often.
- Variant C: variant B's fit (one pair per verdict, the judge at 12.06 dB) on the calibration
  flights above plus the 80 nose-down flights of the threshold's calibration (seed 5002, mission
  physics, -15 and -28 deg; ``score_judge_threshold.py``), 240 flights.
- Held out (scored once): seed 2049, 40 flights each under ``mission`` with the level vehicle, at
  -15 deg and at -28 deg, and under the ``afar`` family (160 flights; the tilted flights count as
  ``mission``): ``bench_adaptive.py --flights 40 --jobs 2 --seed 2049 --family mission [--vehicle
  drag_pitch_deg_per_mps=2.8 | 5.6] --json D/c/test_mission_{level,t15,t28}_2049.json`` and
  ``--family afar --json D/c/test_afar_2049.json``.
- Adopted if its worst |coverage - nominal| there is below that of the shipped masses (B, with the
  judge's new verdicts) and its ``afar`` 90 % interval holds 0.90. Reported beside: the 91 SITL
  flights.
Result: adopted. C's masses: judged 0.1189 / 0.7378, not judged 0.5024 / 0.9893
(``rounds_answer.REGION_MASS``, rounded up). Held out (seed 2049, 121 of 160 judged): shipped
``afar`` 20 / 40, 34 / 40, ``mission`` 47 / 120, 105 / 120 (worst 10.8 points); C ``afar`` 18 /
40, 33 / 40 [70, 91] %, ``mission`` 68 / 120, 117 / 120 (worst 7.5 points). SITL, 91 flights:
ArduCopter 22 / 51, 49 / 51 -> 33 / 51, 51 / 51; PX4 7 / 40, 33 / 40 -> 16 / 40, 39 / 40.

Usage::

    python benchmarks/score_adaptive_regions.py calibrate D/cal_afar_2045.json ... \
        D/cal_mission_2046.json
    python benchmarks/score_adaptive_regions.py score --variant A|B --fitted-on D/cal_*.json \
        D/test_afar_2047.json ...

A file's setting is read from its name (``afar`` or ``mission`` before the seed).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calibrate_regions import LEVELS, masses  # noqa: E402

from mission.evidence import coverage_interval  # noqa: E402
from mission.localize.rounds_answer import PHYSICS_RMS_DB  # noqa: E402
from mission.localize.selfcal import CALIBRATED_MASS  # noqa: E402

SETTINGS = ("afar", "mission")
FOLDS = 5
# the judge's threshold each rule was scored with (the product's moved between them:
# score_judge_threshold.py), and the masses the first rule adopted, so that both rules reproduce
FIRST_RULE_JUDGE_DB = 9.89
SECOND_RULE_JUDGE_DB = 12.06
B_MASS = {True: {0.5: 0.0386, 0.9: 0.4059}, False: {0.5: 0.5503, 0.9: 0.9986}}


def _setting(path: Path) -> str:
    """The physics setting a bench_adaptive JSON was flown under, from its file name."""
    hit = [s for s in SETTINGS if s in path.stem]
    if len(hit) != 1:
        raise SystemExit(f"{path}: name must hold exactly one of {SETTINGS}")
    return hit[0]


def load(
    paths: list[Path], setting: str | None = None, judge_db: float = FIRST_RULE_JUDGE_DB
) -> list[dict]:
    """One record per adaptive flight: setting (``setting``, else from the file name), fold, the
    truth's level, whether the judge fired at threshold ``judge_db``, the printed 90 % area and
    whether the point lies in its own 90 % region."""
    out = []
    given = setting
    for p in paths:
        setting = given or _setting(p)
        for r in json.loads(p.read_text()):
            a = r["adaptive"]
            shown = a.get("shown_regions") or {}
            if shown.get("level") is None:
                continue
            rms = a.get("physics_rms_db")
            out.append(
                {
                    "setting": setting,
                    "fold": int(r["i"]) % FOLDS,
                    "level": float(shown["level"]),
                    "judged": bool(rms) and min(rms) <= judge_db,
                    "area_m2": shown.get("area_m2"),
                    "live_area_m2": a.get("area_m2"),
                    "point_inside": shown.get("point_inside"),
                }
            )
    return out


def fit(rows: list[dict], variant: str) -> dict[bool | None, dict[float, float]]:
    """The variant's masses from ``rows``: A one pair (key None) from the ``afar`` flights; B one
    pair per judge verdict (keys True, False) from both settings."""
    q = np.array([r["level"] for r in rows])
    if variant == "A":
        return {None: masses(q[[r["setting"] == "afar" for r in rows]])}
    judged = np.array([r["judged"] for r in rows])
    return {k: masses(q[judged == k]) for k in (True, False) if (judged == k).any()}


def mass_for(m: dict, r: dict) -> dict[float, float]:
    """The masses a flight's regions take under fitted masses ``m`` (B: by its judge verdict; a
    stratum without calibration flights falls back to the pooled one)."""
    if None in m:
        return m[None]
    return m.get(r["judged"]) or next(iter(m.values()))


def covered(rows: list[dict], m_of) -> dict[str, dict[float, tuple[int, int]]]:
    """Setting -> level -> (flights inside, flights) with each flight's masses ``m_of(r)``."""
    out = {}
    for s in SETTINGS:
        rs = [r for r in rows if r["setting"] == s]
        out[s] = {lev: (sum(r["level"] < m_of(r)[lev] for r in rs), len(rs)) for lev in LEVELS}
    return out


def worst(cov: dict) -> float:
    """The largest |coverage - nominal| (points) over settings and levels."""
    return max(
        abs(100 * k / n - 100 * lev) for per in cov.values() for lev, (k, n) in per.items() if n
    )


def cross_fitted(rows: list[dict], variant: str) -> dict:
    """Coverage of ``variant`` with each fold's flights given masses fitted on the other folds."""
    out = {s: {lev: [0, 0] for lev in LEVELS} for s in SETTINGS}
    for f in range(FOLDS):
        train = [r for r in rows if r["fold"] != f]
        test = [r for r in rows if r["fold"] == f]
        m = fit(train, variant)
        for s, per in covered(test, lambda r, m=m: mass_for(m, r)).items():
            for lev, (k, n) in per.items():
                out[s][lev][0] += k
                out[s][lev][1] += n
    return {s: {lev: tuple(v) for lev, v in per.items()} for s, per in out.items()}


def _line(name: str, cov: dict) -> str:
    cells = []
    for s in SETTINGS:
        for lev in LEVELS:
            k, n = cov[s][lev]
            ci = coverage_interval(k, n) if n else None
            cells.append(
                f"{s} {int(100 * lev)} %: {k}/{n}"
                + (f" [{100 * ci.lo:.0f}, {100 * ci.hi:.0f}]" if ci else "")
            )
    return f"{name}: " + "; ".join(cells) + f"; worst {worst(cov):.1f} points"


def calibrate(paths: list[Path]) -> str:
    """The rule's choice on the calibration flights; prints each variant's cross-fitted coverage
    and the masses fitted on all of them."""
    rows = load(paths)
    print(f"{len(rows)} adaptive flights; judged {sum(r['judged'] for r in rows)}")
    print(_line("today", covered(rows, lambda r: CALIBRATED_MASS)))
    scores = {}
    for v in ("A", "B"):
        cov = cross_fitted(rows, v)
        scores[v] = worst(cov)
        print(_line(f"{v} (cross-fitted)", cov))
        print(f"  {v} masses on all: {fit(rows, v)}")
    choice = min(("A", "B"), key=lambda v: (scores[v], v))
    print(f"chosen: {choice}")
    return choice


def _median(vals) -> float:
    v = [x for x in vals if x is not None]
    return float(np.median(v)) if v else float("nan")


def score(paths: list[Path], variant: str, m: dict, judge_db: float = FIRST_RULE_JUDGE_DB) -> bool:
    """The rule's verdict on held-out flights flown with the chosen masses ``m`` in place, the
    judge at ``judge_db``."""
    rows = load(paths, judge_db=judge_db)
    today = covered(rows, lambda r: CALIBRATED_MASS)
    new = covered(rows, lambda r: mass_for(m, r))
    print(_line("today", today))
    print(_line(f"{variant}", new))
    for s in SETTINGS:
        rs = [r for r in rows if r["setting"] == s]
        inside = [r["point_inside"] for r in rs if r["point_inside"] is not None]
        print(
            f"{s}: median 90 % area today {_median(r['live_area_m2'] for r in rs):.0f} m^2, "
            f"{variant} {_median(r['area_m2'] for r in rs):.0f} m^2; point inside its 90 % region "
            f"{sum(inside)}/{len(inside)}"
        )
    ci = {(s, lev): coverage_interval(*new[s][lev]) for s in SETTINGS for lev in LEVELS}
    c1 = ci[("afar", 0.9)].lo <= 0.9 <= ci[("afar", 0.9)].hi and (
        ci[("afar", 0.5)].lo <= 0.5 <= ci[("afar", 0.5)].hi
    )
    c2 = ci[("mission", 0.9)].hi >= 0.9
    c3 = worst(new) < worst(today)
    ok = c1 and c2 and c3
    print(f"conditions: 1 {c1}, 2 {c2}, 3 {c3} -> {'adopted' if ok else 'not adopted'}")
    return ok


def sitl(stores: list[Path]) -> None:
    """Reported after the verdict (decides nothing): the printed regions of every adaptive flight
    flown against a real autopilot in SITL (``bench_sitl_seeds.py`` stores, each log answered
    by this code), with the chosen masses and with today's (the live method's own regions)."""
    from bench_sitl_seeds import stored_flights  # noqa: PLC0415

    from mission.localize.api import localize_log  # noqa: PLC0415
    from mission.localize.methods import ADAPTIVE_METHOD  # noqa: PLC0415
    from mission.workshop.evaluate_suite import region_coverage  # noqa: PLC0415

    counts = {}
    for r, log in stored_flights(stores, "adaptive"):
        est = localize_log(log)
        truth = log.truth_enu
        if est.method != "rounds" or truth is None:
            continue
        rms = est.extras.get("physics_rms_db")
        judged = bool(rms) and min(rms) <= PHYSICS_RMS_DB
        live = est.components[ADAPTIVE_METHOD]
        for name, e in (("chosen", est), ("today", live)):
            c = counts.setdefault((r["autopilot"], name), {"50": 0, "90": 0, "n": 0, "a": []})
            cov = region_coverage(e, truth[:2])
            c["50"] += cov["50"]
            c["90"] += cov["90"]
            c["n"] += 1
            c["a"].append(e.region(0.9).area_m2)
        print(
            f"{r['autopilot']:9s} seed {r['seed']:2d}: error {est.error_m:5.1f} m, judged "
            f"{judged}, 90 % held: chosen {region_coverage(est, truth[:2])['90']}, today "
            f"{region_coverage(live, truth[:2])['90']}"
        )
    for (ap, name), c in sorted(counts.items()):
        print(
            f"{ap:9s} {name:6s}: 50 % {c['50']}/{c['n']}, 90 % {c['90']}/{c['n']}, median 90 % "
            f"area {np.median(c['a']):.0f} m^2"
        )


def score_tilted(
    held: list[Path], cal: list[Path], tilted: list[Path], stores: list[Path] | None = None
) -> bool:
    """The second rule: variant C (B's fit with the nose-down calibration flights) against the
    shipped masses on the held-out flights of seed 2049."""
    db = SECOND_RULE_JUDGE_DB
    m_c = fit(load(cal, judge_db=db) + load(tilted, "mission", db), "B")
    shipped = B_MASS
    rows = load(held, judge_db=db)
    print(f"{len(rows)} held-out flights; judged {sum(r['judged'] for r in rows)}; C masses {m_c}")
    today = covered(rows, lambda r: mass_for(shipped, r))
    new = covered(rows, lambda r: mass_for(m_c, r))
    print(_line("shipped", today))
    print(_line("C", new))
    ci = coverage_interval(*new["afar"][0.9])
    ok = worst(new) < worst(today) and ci.lo <= 0.9 <= ci.hi
    print(f"-> {'adopted' if ok else 'not adopted'}")
    if stores:
        _sitl_levels(stores, {"shipped": shipped, "C": m_c})
    return ok


def _sitl_levels(stores: list[Path], masses_by_name: dict) -> None:
    """Coverage on the stored adaptive SITL flights under each set of masses, from the truth's
    level in each answer's posterior (reported beside the second rule)."""
    from bench_sitl_seeds import stored_flights  # noqa: PLC0415

    from mission.localize.api import localize_log  # noqa: PLC0415

    rows = []
    for r, log in stored_flights(stores, "adaptive"):
        est = localize_log(log)
        if est.method != "rounds" or log.truth_enu is None:
            continue
        rms = est.extras.get("physics_rms_db")
        t = log.truth_enu
        rows.append(
            {
                "autopilot": r["autopilot"],
                "judged": bool(rms) and min(rms) <= PHYSICS_RMS_DB,
                "level": est.posterior.hpd_level(float(t[0]), float(t[1])),
            }
        )
    for ap in sorted({r["autopilot"] for r in rows}):
        rs = [r for r in rows if r["autopilot"] == ap]
        for name, m in masses_by_name.items():
            k = {lev: sum(r["level"] < mass_for(m, r)[lev] for r in rs) for lev in LEVELS}
            print(f"SITL {ap:9s} {name:7s}: 50 % {k[0.5]}/{len(rs)}, 90 % {k[0.9]}/{len(rs)}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("calibrate")
    c.add_argument("files", nargs="+", type=Path)
    s = sub.add_parser("score")
    s.add_argument("--variant", choices=("A", "B"), required=True)
    s.add_argument("--fitted-on", nargs="+", type=Path, required=True, help="the calibration files")
    s.add_argument("files", nargs="+", type=Path)
    c2 = sub.add_parser("tilted", help="the second rule")
    c2.add_argument("files", nargs="+", type=Path, help="held-out rows (seed 2049)")
    c2.add_argument("--cal", nargs="+", type=Path, required=True)
    c2.add_argument("--tilted", nargs="+", type=Path, required=True)
    c2.add_argument("--sitl", nargs="*", type=Path, default=[], help="SITL stores, reported beside")
    t = sub.add_parser("sitl")
    t.add_argument("stores", nargs="+", type=Path, help="bench_sitl_seeds.py flights.jsonl files")
    a = p.parse_args(argv)
    if a.cmd == "calibrate":
        calibrate(a.files)
    elif a.cmd == "tilted":
        score_tilted(a.files, a.cal, a.tilted, a.sitl)
    elif a.cmd == "sitl":
        sitl(a.stores)
    else:
        score(a.files, a.variant, fit(load(a.fitted_on), a.variant))
    return 0


if __name__ == "__main__":
    sys.exit(main())
