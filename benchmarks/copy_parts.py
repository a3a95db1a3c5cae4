"""Which part of a family's draw makes its copies of the real flights hard to localize.

The design-held checks (``ppc_same_design.py``) find every family's copies of the six real flights
about twice as hard as the real flights. This script takes the copies apart, on the real tracks,
attitudes and transmitters (mission/gap/README.md, "Fades, not peaks"):

- ``real``: the logged RSS;
- ``fitted model``: each flight's own family fit (the ladder's effects on that flight, and its
  offset), with no residual at all;
- ``model + real resid. shifted``: that model plus the flight's own residual (real minus
  model) moved along the flight by a quarter, a half and three quarters of its samples: the real
  residual's size and its structure along the track, no longer where it was;
- ``model + real resid. locked``: that model plus the flight's residual in place on the samples the
  sounder read locked, the out-of-lock ones at the model (plus the locked samples' median
  residual); and ``model + out-of-lock resid.``: the model everywhere, the real residual in place on
  the out-of-lock samples only: which part of the real residual's place helps (stop 58: the lock
  losses follow the fades, ``experiments/lock_mechanism.py``);
- per draw of ``--family`` (``--k`` per flight): its model with the white noise, then with the
  per-flight nuisance (the drift) added, then with the shadowing added, then everything: what
  ``simulate_rss`` draws, part by part (the same random numbers in each arm).

Each arm is localized as the real flight is (the default, selfcal and ``rfsl_spiral_e2r``; the grid
is left out), and the mean error over flights (and draws) is printed with a 90 % bootstrap interval
over the six flights, and the share of answers beyond 150 m.

    python benchmarks/copy_parts.py --mat ../shared/data/afar2023/mat --family afar --k 6
"""

from __future__ import annotations

import json
import os
import tempfile
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from ppc_same_design import MODELS, design_parser, real_flights
from rich.console import Console
from rich.progress import track
from score_decision import methods, real_kwargs

from mission.flightlog import FlightLog, read_flight_log
from mission.flightlog.schema import QUALITY_COLUMN, out_of_lock
from mission.gap.align import afar2023_flights
from mission.gap.diagnose import decimate_flight
from mission.gap.familyfit import effects_of_ladder, fit_family
from mission.gap.fit import FitConfig
from mission.localize.api import localize_log
from mission.physics.family import FamilyDraw, load_family, simulate_parts

LABELS = ("fusion (default)", "selfcal", "net rfsl_spiral_e2r")
SHIFTS = (0.25, 0.5, 0.75)
FAR_M = 150.0
REPO = Path(__file__).resolve().parents[1]


def fitted_models(mat: str) -> dict[str, tuple[dict, float]]:
    """Per real flight (``288_loc_1`` ...), its own family fit: (model spec, offset dB)."""
    ladder = json.loads((REPO / "mission" / "data" / "afar_family.json").read_text())["ladder"]
    six = afar2023_flights(Path(mat))
    cfg = FitConfig(split="flights", loss="soft_l1", seed=0, rate_hz=3.0, processes=2)
    effects, _ = effects_of_ladder(ladder)
    _, fits = fit_family([decimate_flight(f, 3.0) for f in six], effects, cfg, structure=True)
    return {ft.name.replace("-loc", "_loc_"): (ft.spec, ft.offset_db) for ft in fits}


def _errors(log: FlightLog, rss: np.ndarray, team: str, specs: dict[str, str]) -> dict:
    ok = np.isfinite(np.asarray(log["rss_dbm"], dtype=float))
    rss = np.where(ok, rss, np.nan)
    lg = FlightLog({**log.columns, "rss_dbm": rss}, dict(log.meta), log.path, [])
    tx = log.truth_enu
    out = {}
    for label in LABELS:
        est = localize_log(lg, **real_kwargs(specs[label], team))
        out[label] = float(np.hypot(est.x_m - tx[0], est.y_m - tx[1]))
    return out


def one_flight(job: tuple) -> tuple[int, dict[str, list[dict]]]:
    """Every arm of one real flight: {arm: [errors by method, one per draw or shift]}."""
    i, path, team, spec, offset, family, k, seed = job
    specs = methods(MODELS, [])
    log = read_flight_log(path)
    enu, tx = log.enu(), log.truth_enu
    att = log.attitude_rad
    att = np.zeros_like(enu) if att is None else np.nan_to_num(att)
    real = np.asarray(log["rss_dbm"], dtype=float)
    model = np.asarray(FamilyDraw(spec, 0.0, 1.0, 0.0, 0.0).model().rss_dbm(tx, enu, att))
    model = model + offset
    arms: dict[str, list[dict]] = {"real": [_errors(log, real, team, specs)]}
    arms["fitted model"] = [_errors(log, model, team, specs)]
    ok = np.flatnonzero(np.isfinite(real))
    r = real[ok] - model[ok]

    def model_plus(resid: np.ndarray) -> dict:
        """The errors with the RSS the fitted model plus ``resid`` on the rows that logged one."""
        rss = np.full_like(real, np.nan)
        rss[ok] = model[ok] + resid
        return _errors(log, rss, team, specs)

    arms["model + real resid. shifted"] = [
        model_plus(np.roll(r - np.median(r), int(s * len(ok)))) for s in SHIFTS
    ]
    unlocked = out_of_lock(log[QUALITY_COLUMN])[ok]
    base = np.median(r[~unlocked])
    arms["model + real resid. locked"] = [model_plus(np.where(unlocked, base, r))]
    arms["model + out-of-lock resid."] = [model_plus(np.where(unlocked, r, base))]
    fam = load_family(family)
    rng = np.random.default_rng([seed, i])
    for _ in range(k):
        for arm, rss in family_parts(fam.draw(rng), tx, enu, att, rng).items():
            arms.setdefault(arm, []).append(_errors(log, rss, team, specs))
    return i, arms


def family_parts(
    d: FamilyDraw, tx: np.ndarray, enu: np.ndarray, att: np.ndarray, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """One draw's RSS part by part (``physics.family.simulate_parts``: the random numbers of
    ``simulate_rss`` in its order), so that ``family: all`` is exactly its copy."""
    p = simulate_parts(d, tx, enu, att, rng)
    m, noise, sh, nu = p["model"], p["noise"], p["shadowing"], p["nuisance"]
    return {
        "family: model + noise": m + noise,
        "family: + drift": m + noise + nu,
        "family: + shadowing": m + noise + sh,
        "family: all": m + noise + sh + nu,
    }


def bootstrap_mean(per_flight: np.ndarray, rng: np.random.Generator, n: int = 4000) -> list:
    """90 % interval of the mean of the flights' means (flights resampled)."""
    idx = rng.integers(0, len(per_flight), (n, len(per_flight)))
    return np.quantile(per_flight[idx].mean(axis=1), [0.05, 0.95]).tolist()


def main() -> None:
    a = design_parser(__doc__.splitlines()[0], 6, "write every arm's errors here").parse_args()
    con = Console(width=80)
    fits = fitted_models(a.mat)
    with tempfile.TemporaryDirectory() as tmp:
        flights = real_flights(a.mat, tmp)
        jobs = [
            (i, p, team, *fits[name], a.family, a.k, a.seed)
            for i, (name, team, p) in enumerate(flights)
        ]
        with get_context("spawn").Pool(a.workers) as pool:
            done = dict(
                track(pool.imap_unordered(one_flight, jobs), total=len(jobs), description="flights")
            )
    rng = np.random.default_rng(a.seed)
    con.print(f"family {a.family}, {a.k} draws per flight, seed {a.seed}; mean error m [90 %]")
    con.print(f"{'arm':30} " + " ".join(f"{lab.split()[-1][:15]:>15}" for lab in LABELS))
    table = {}
    for arm in done[0]:
        cells = []
        for label in LABELS:
            per = np.array([np.mean([e[label] for e in done[i][arm]]) for i in sorted(done)])
            every = np.array([e[label] for i in sorted(done) for e in done[i][arm]])
            lo, hi = bootstrap_mean(per, rng)
            table.setdefault(arm, {})[label] = {
                "mean": float(per.mean()),
                "ci90": [lo, hi],
                "per_flight": per.round(1).tolist(),
                "beyond_150_m": float((every > FAR_M).mean()),
            }
            cells.append(f"{per.mean():5.1f} [{lo:3.0f},{hi:3.0f}]")
        con.print(f"{arm[:30]:30} " + " ".join(f"{c:>15}" for c in cells))
    if a.json:
        Path(a.json).write_text(json.dumps({"family": a.family, "k": a.k, "arms": table}, indent=1))


if __name__ == "__main__":
    main()
