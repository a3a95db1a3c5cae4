"""Should selfcal also try the antenna the real flights show overhead (issue 32, stop 58)?

Why: the real RSS rises from 15-30 to 30-45 degrees of elevation and falls 7-16 dB straight above
the transmitter (``mission.gap.overhead.elevation_profile``; mission/gap/README.md, "What the
antennas do overhead"); the measured pattern selfcal picks on every real flight rises 8 dB there.
A single dipole hypothesis localizes team 288's flights better and fits them worse
(``experiments/antenna_overhead.py``).  The candidate adds one UAV-antenna hypothesis to selfcal's
set: the **empirical pair**, a link gain by elevation read off real flights, so the in-sample fit
can choose it where it fits.

Rule (written 2026-11-29 15:50 UTC and committed before any flight was scored with the candidate):
- The empirical pair: at the band centres 37.5, 52.5, 67.5, 82.5 deg the mean over flights of
  ``elevation_profile`` (the flights holding the band), 0 dB at 7.5 and 22.5 deg, the 82.5 deg
  value at 90 deg, linear between (a band that no flight holds takes the band below's value).
  Read off the other team's three flights for a real flight (leave one team out), off all six for a
  benchmark flight.
- Candidate: ``fusion`` with its selfcal member given that one more hypothesis (the mean of that
  selfcal's point and ``rfsl_spiral_e2r``'s). Incumbent: ``fusion`` as shipped, what the user sees.
- Evidence: the six real flights (teams 288 and 328) and the benchmark cache (``rfsl dataset --suite
  unseen --logs --family mission/data/afar_family.json --n 200 --seed 2026``, all 200 flights:
  nothing is fitted on them).
- Decision: the issue-24 rule (``mission.workshop.decision.pooled_decision``, real flights resampled
  by team): adopted if the candidate wins. Reported beside, not deciding: selfcal with and without
  the hypothesis on both sources (paired 90 % intervals), and how often the hypothesis is chosen.

    python benchmarks/score_overhead_antenna.py --suite-dir /tmp/suite_fam \
        --mat ../shared/data/afar2023/mat --workers 2
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _scoring import flight_with_truth, real_logs_and_pool, scoring_parser

import mission.localize.selfcal as selfcal
from mission.evidence import mean_interval, paired_difference
from mission.flightlog import read_flight_log
from mission.gap.familyfit import team_of
from mission.gap.overhead import EL_BANDS_DEG, elevation_profile
from mission.localize.api import _in_log_frame, localize_log, search_area
from mission.localize.methods import method_entry
from mission.localize.preprocess import select_samples
from mission.workshop.decision import pooled_decision

CANDIDATE = "fusion, selfcal with the empirical pair"
INCUMBENT = "fusion"
LABEL = "empirical pair"


@dataclass(frozen=True)
class EmpiricalPair(selfcal.DipolePair):
    """A link gain by the transmitter's elevation of the link (``el_deg`` ascending, ``gain_db``),
    interpolated linearly: selfcal looks it up as it does the dipole pair's."""

    el_deg: tuple[float, ...] = (0.0, 90.0)
    gain_db: tuple[float, ...] = (0.0, 0.0)
    name: str = LABEL

    def link_gain_dbi(self, el_tx, el_uav):
        el = np.degrees(np.abs(np.asarray(el_tx, dtype=float)))
        return np.interp(el, self.el_deg, self.gain_db)


def empirical_pair(logs) -> EmpiricalPair:
    """The rule's link gain read off ``logs`` (module docstring)."""
    means = np.array([elevation_profile(lg)[0] for lg in logs])  # (flights, bands)
    centres = np.convolve(EL_BANDS_DEG, [0.5, 0.5], "valid")
    gains = [0.0, 0.0]
    for b in range(2, len(centres)):
        col = means[:, b][np.isfinite(means[:, b])]
        gains.append(float(col.mean()) if len(col) else gains[-1])
    return EmpiricalPair(el_deg=tuple([*centres, 90.0]), gain_db=tuple([*gains, gains[-1]]))


@contextlib.contextmanager
def with_pair(pair: EmpiricalPair):
    """selfcal's hypotheses with ``pair`` appended, for the duration (this process only)."""
    original = selfcal.antenna_hypotheses

    def hypotheses(kinds=selfcal.HYPOTHESIS_KINDS, heading_step_deg=30.0):
        return [*original(kinds, heading_step_deg), (LABEL, pair, 0.0, False)]

    selfcal.antenna_hypotheses = hypotheses
    try:
        yield
    finally:
        selfcal.antenna_hypotheses = original


def one(job: tuple) -> dict:
    """The incumbent's point, its two members', selfcal's with the pair, and the truth (log ENU)."""
    kind, src, i, pair = job
    log, truth = flight_with_truth(kind, src, i)
    est = localize_log(log, method="fusion")
    comp = est.extras["components"]
    net = np.asarray(comp["rfsl_spiral_e2r.onnx"], dtype=float)
    part, _ = select_samples(log)
    with with_pair(pair):
        loc = selfcal.SelfCalibratingGrid(area=search_area(log))
        s = _in_log_frame(loc, loc.predict(part), log.origin, method_entry("selfcal").frame)
    a2 = np.array([s.x_m, s.y_m])
    return {
        "truth": np.asarray(truth, dtype=float),
        INCUMBENT: np.array([est.x_m, est.y_m]),
        "selfcal": np.asarray(comp["selfcal"], dtype=float),
        "selfcal with the pair": a2,
        CANDIDATE: 0.5 * (a2 + net),
        "chosen": s.fit.antenna == LABEL,
    }


def errors(rows: list[dict], key: str) -> np.ndarray:
    return np.array([np.hypot(*(r[key] - r["truth"])) for r in rows])


def main() -> None:
    args = scoring_parser(__doc__).parse_args()
    with real_logs_and_pool(args) as (real, ex):
        logs = [read_flight_log(p) for p in real]
        teams = [team_of(Path(p).stem) for p in real]
        pairs = [
            empirical_pair([lg for lg, t in zip(logs, teams, strict=True) if t != team])
            for team in teams
        ]
        every = empirical_pair(logs)
        for team in sorted(set(teams)):
            p = pairs[teams.index(team)]
            print(f"pair for team {team}: " + " ".join(f"{g:+.1f}" for g in p.gain_db[2:]))
        print("pair for the benchmark: " + " ".join(f"{g:+.1f}" for g in every.gain_db[2:]))
        jobs = [("real", str(p), 0, q) for p, q in zip(real, pairs, strict=True)]
        rows_r = list(ex.map(one, jobs))
        rows_b = list(
            ex.map(one, [("suite", args.suite_dir, i, every) for i in range(args.n)], chunksize=4)
        )
    for label, rows, groups in (("real (teams)", rows_r, teams), ("benchmark", rows_b, None)):
        print(f"{label}, n={len(rows)}; chosen on {sum(r['chosen'] for r in rows)}")
        for key in ("selfcal", "selfcal with the pair", INCUMBENT, CANDIDATE):
            print(f"  {key:40s} {mean_interval(errors(rows, key), groups).fmt()} m")
        for a, b in (("selfcal with the pair", "selfcal"), (CANDIDATE, INCUMBENT)):
            d = paired_difference(errors(rows, a), errors(rows, b), groups)
            print(f"  {a} - {b}: {d.fmt()} m")
    if rows_r:
        print("real per flight (incumbent / candidate):")
        print(
            "  "
            + " ".join(
                f"{x:.1f}/{y:.1f}"
                for x, y in zip(errors(rows_r, INCUMBENT), errors(rows_r, CANDIDATE), strict=True)
            )
        )
    dec = pooled_decision(
        {k: errors(rows_r, k) for k in (INCUMBENT, CANDIDATE)},
        teams,
        {k: errors(rows_b, k) for k in (INCUMBENT, CANDIDATE)},
        INCUMBENT,
    )
    m = dec["methods"][CANDIDATE]
    print(
        f"pooled relative difference {m['pooled'].fmt(3)} (real {m['real'].fmt(3)}, bench "
        f"{m['bench'].fmt(3)}): {'ADOPTED' if dec['changed'] else 'not adopted'}"
    )


if __name__ == "__main__":
    main()
