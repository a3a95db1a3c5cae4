"""Where the real RSS leaves the model: the AFAR sounder losing lock, flagged by its own quality.

Why: every localizer's residual on the AFAR flights has a heavy low tail that the physics family
draws as shadowing (mission/gap/README.md), and per-flight evidence over candidates drowned in it
(models/README.md, issue 32).  The MAT files carry ``mquality`` (correlation peak over noise, dB),
which no importer reads.  This script asks, per flight, with the transmitter at its label:
1. how the residual under the ``afar`` preset (the fold fitted without the flight's team) splits
   between samples whose quality says the sounder was locked (>= ``--lock``) and the rest, and how
   the unlocked share grows as the model's predicted level falls (a receiver threshold, not a
   distance law);
2. what the search's own model class reaches on the locked samples (the oracle of
   ``oracle_real.py``: antenna hypothesis and offset fitted at the truth, then the position
   searched), and the profiled search (selfcal's model) on all samples, on the locked ones, and
   with each unlocked cell read as an upper bound (``censored_search``: under the locked cells'
   10th percentile, or under the flight's lock floor of ``lock_mechanism.py``);
3. whether the flight's held-out evidence, which issue 32's stage weighs candidates by, ranks the
   label itself above the members' candidates, with and without the unlocked samples;
4. the members and the default with the out-of-lock samples withheld (under 50 or 55 dB) or their
   power clamped to the flight's locked 5th percentile, each against today's with its paired 90 %
   bootstrap interval over the six flights.  Exploration: no rule was written for it, and the
   benchmark cannot judge it (its family draws no lock losses).

    python experiments/receiver_lock.py --mat ../shared/data/afar2023/mat          # ~2 min
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from experiments.oracle_real import SUSPECT, oracle_error, search_setup
from mission.cells import cell_average
from mission.evidence import paired_difference
from mission.flightlog import read_flight_log
from mission.flightlog.schema import QUALITY_COLUMN, SOUNDER_LOCK_DB, lock_floor_db, out_of_lock
from mission.importers.afar import AFAR2023_FOLD_WITHOUT, import_afar_mat
from mission.localize.api import localize_log, make_localizer, search_area
from mission.localize.candidates import Candidate
from mission.localize.classical import as_flight
from mission.localize.evidence_stage import member_candidates, score_candidates
from mission.localize.preprocess import select_samples
from mission.localize.selfcal import (
    _geometry,
    hypothesis_residuals,
    hypothesis_ssr,
)
from mission.workshop.evaluate import afar_truth

LEVEL_BANDS_DB = (-40.0, -10.0, -5.0, 0.0, 5.0, 10.0, 50.0)  # model level + offset, mpower dB


def quality_log(mat: Path, tmp: Path):
    """The flight imported with its label (the import keeps ``mquality`` as ``QUALITY_COLUMN``)."""
    truth, _ = afar_truth(mat)
    return read_flight_log(import_afar_mat(mat, tmp, truth=truth, overwrite=True).out_path)


def label_residual(log, part, lock_db: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(residual, model level, locked) per sample of ``part`` with the transmitter at the label,
    under the ``afar`` fold fitted without the flight's team; the offset is the locked samples'
    median residual, so the residual is about that and the level is in the sounder's dB."""
    f = as_flight(part)
    name = log.meta["source"]["file"].replace("results_useful_ori_exp_", "")[:3]
    grid = make_localizer("grid", physics_preset=f"afar:{AFAR2023_FOLD_WITHOUT[name]}")
    t = np.asarray(log.truth_enu[:2])[None, :]
    pred = grid.candidate_rss(t, f.enu_m, f.attitude_rad)[0]
    r = f.rss_dbm - pred
    locked = np.asarray(part[QUALITY_COLUMN]) >= lock_db
    off = float(np.median(r[locked]))
    return r - off, pred + off, locked


def residual_split(log, part, lock_db: float) -> dict:
    """Residual at the label under the team-held-out ``afar`` fold, locked against unlocked
    samples, and the unlocked share by the model's predicted level."""
    r, level, locked = label_residual(log, part, lock_db)
    bands = []
    for lo, hi in zip(LEVEL_BANDS_DB[:-1], LEVEL_BANDS_DB[1:], strict=True):
        m = (level >= lo) & (level < hi)
        if m.sum() >= 50:
            bands.append((lo, hi, int(m.sum()), float(np.mean(~locked[m]))))
    return {
        "n": len(r),
        "unlocked": float(np.mean(~locked)),
        "locked_rms": float(np.sqrt(np.mean(r[locked] ** 2))),
        "unlocked_med": float(np.median(r[~locked])) if (~locked).any() else float("nan"),
        "bands": bands,
    }


def searches(log, part, lock_db: float) -> dict:
    """Errors (m) of the oracle (antenna and offset fitted at the label) and of the profiled
    search, on all cruise samples and on the locked ones, same 2 m grid as ``oracle_real.py``."""
    f_all = as_flight(part)
    q = np.asarray(part[QUALITY_COLUMN])
    sc, hyps, grid, truth = search_setup(log, f_all)
    out = {}
    for tag, keep in (("all", np.ones(len(q), bool)), ("locked", q >= lock_db)):
        cells = cell_average(_subset(f_all, keep), sc.cell_m, sc.altitude_gap_m)
        out[f"oracle {tag}"] = oracle_error(cells, grid, truth, hyps, sc.tx_height_m, False)[0]
        ssr, _ = hypothesis_ssr(grid, cells, hyps, sc.tx_height_m)
        out[f"search {tag}"] = float(np.hypot(*(grid[int(np.argmin(ssr.min(axis=0)))] - truth)))
    out["search censored"] = censored_search(f_all, q >= lock_db, sc, hyps, grid, truth)
    floor = lock_floor_db(part["rss_dbm"], q, lock_db)
    out["censored at floor"] = censored_search(f_all, q >= lock_db, sc, hyps, grid, truth, floor)
    return out


def censored_search(
    f_all, locked: np.ndarray, sc, hyps, grid, truth, t_db: float | None = None
) -> float:
    """The profiled search on the locked cells, each unlocked cell read as a bound: the signal
    there was below ``T`` (``t_db``: the flight's lock floor, ``schema.lock_floor_db``; None: the
    10th percentile of the locked cells' RSS; no truth used either way); a candidate pays
    ``max(0, model - T)^2`` per unlocked cell, the model's offset fitted on the locked cells."""
    cl = cell_average(_subset(f_all, locked), sc.cell_m, sc.altitude_gap_m)
    cu = cell_average(_subset(f_all, ~locked), sc.cell_m, sc.altitude_gap_m)
    if t_db is None:
        t_db = float(np.percentile(cl.rss_dbm, 10))
    pg, el, az, elu = _geometry(grid, cl, sc.tx_height_m)
    pgu, elx, azu, eluu = _geometry(grid, cu, sc.tx_height_m)
    y = cl.rss_dbm.astype(np.float32)[None, :]
    best = np.full(len(grid), np.inf)
    for r, g in zip(
        hypothesis_residuals(y - pg, el, az, hyps, None, elu),
        hypothesis_residuals(-pgu, elx, azu, hyps, None, eluu),
        strict=True,
    ):
        c = r.mean(axis=1)
        ssr = np.einsum("km,km->k", r, r) - r.shape[1] * c.astype(np.float64) ** 2
        over = np.maximum(c[:, None] - g - t_db, 0.0)
        best = np.minimum(best, ssr + np.einsum("km,km->k", over, over))
    return float(np.hypot(*(grid[int(np.argmin(best))] - truth)))


def truth_evidence(log, part, lock_db: float) -> dict:
    """Nats by which the label's own held-out evidence (the stage's blocked scores,
    ``evidence_stage.score_candidates``) trails the best of the members' candidates (the grid on
    the team-held-out fold), on all cruise samples and on the locked ones: 0 when the label leads.
    No scheme built on this evidence can pick a point the evidence ranks below another."""
    name = log.meta["source"]["file"].replace("results_useful_ori_exp_", "")[:3]
    cands, _ = member_candidates(
        part,
        log.origin,
        search_area(log),
        physics_preset=f"afar:{AFAR2023_FOLD_WITHOUT[name]}",
    )
    t = np.asarray(log.truth_enu[:2])
    cands = [*cands, Candidate(float(t[0]), float(t[1]), "label")]
    out = {}
    locked = np.asarray(part[QUALITY_COLUMN]) >= lock_db
    for tag, p in (("all", part), ("locked", part.select(locked))):
        out[tag] = float(-score_candidates(p, cands).evidence[-1])
    return out


MEMBERS = ("selfcal", "grid", "rfsl_spiral_e2r", "fusion")
VARIANTS = ("as today", "without q < 50", "without q < 55", "clamped to lock p5")


def member_errors(log) -> dict[str, dict[str, float]]:
    """{variant: {member: error m}}: the members and the default (fusion) on the whole log as
    today, without the rows under 50 or 55 dB quality, and with the out-of-lock rows' power
    clamped to the 5th percentile of the locked rows' (weak, not absurd)."""
    q, p = np.asarray(log[QUALITY_COLUMN]), np.asarray(log["rss_dbm"])
    locked = ~out_of_lock(q)
    clamped = log.select(np.ones(len(q), bool))
    clamped.columns["rss_dbm"] = np.where(locked, p, np.percentile(p[locked], 5))
    logs = {
        VARIANTS[0]: log,
        VARIANTS[1]: log.select(~out_of_lock(q, 50.0)),
        VARIANTS[2]: log.select(~out_of_lock(q, 55.0)),
        VARIANTS[3]: clamped,
    }
    team = log.meta["source"]["file"].replace("results_useful_ori_exp_", "")[:3]
    kw = {
        "selfcal": {"method": "selfcal"},
        "grid": {"method": "grid", "physics_preset": f"afar:{AFAR2023_FOLD_WITHOUT[team]}"},
        "rfsl_spiral_e2r": {"model_path": "models/rfsl_spiral_e2r.onnx"},
        "fusion": {"method": "fusion"},
    }
    t = np.asarray(log.truth_enu[:2])
    out = {}
    for v, lg in logs.items():
        out[v] = {}
        for m in MEMBERS:
            e = localize_log(lg, **kw[m])
            out[v][m] = float(np.hypot(e.x_m - t[0], e.y_m - t[1]))
    return out


def print_member_table(names: list[str], errs: list[dict]) -> None:
    """Each variant's mean error per member, and its paired difference from today's with the
    90 % bootstrap interval over the six flights (``evidence.paired_difference``)."""
    print("out-of-lock samples withheld or clamped: mean of 6 m, vs today [90 %]:")
    for m in MEMBERS:
        today = [e[VARIANTS[0]][m] for e in errs]
        print(f"  {m}: today {np.mean(today):.1f}")
        for v in VARIANTS[1:]:
            a = [e[v][m] for e in errs]
            print(f"    {v:20s} {np.mean(a):5.1f}  {paired_difference(a, today).fmt()}")
    print("  flights: " + ", ".join(names))


def _subset(f, keep: np.ndarray):
    """The samples of ``f`` where ``keep``."""
    return replace(
        f,
        enu_m=f.enu_m[keep],
        rss_dbm=f.rss_dbm[keep],
        attitude_rad=None if f.attitude_rad is None else f.attitude_rad[keep],
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--mat", required=True, help="folder of the AFAR 2023 .mat files")
    ap.add_argument(
        "--lock", type=float, default=SOUNDER_LOCK_DB, help="quality (dB) read as locked"
    )
    args = ap.parse_args()
    rows, members = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for mat in sorted(Path(args.mat).glob("*.mat")):
            log = quality_log(mat, Path(tmp))
            part, _ = select_samples(log)
            name = mat.stem.replace("results_useful_ori_exp_", "")
            split = residual_split(log, part, args.lock)
            rows.append(
                (name, split, searches(log, part, args.lock), truth_evidence(log, part, args.lock))
            )
            members.append(member_errors(log))
    print(f"quality >= {args.lock:g} dB read as locked; residual at the label, afar fold")
    for name, s, *_ in rows:
        print(
            f"{name}: {100 * s['unlocked']:4.1f} % of {s['n']} unlocked; locked rms "
            f"{s['locked_rms']:.1f} dB, unlocked median {s['unlocked_med']:+.1f}"
        )
        for lo, hi, n, u in s["bands"]:
            print(
                f"  model level {lo:+4.0f} .. {hi:+3.0f} dB: {n:5d} samples, "
                f"{100 * u:3.0f} % unlocked"
            )
    keys = list(rows[0][2])
    print("errors, m:")
    for k in keys:
        e = np.array([r[2][k] for r in rows])
        print(
            f"  {k:16s} " + " ".join(f"{x:5.1f}" for x in e) + f"  mean {e.mean():5.1f}"
            f" (5: {np.delete(e, SUSPECT).mean():4.1f})"
        )
    print("  flights: " + ", ".join(r[0] for r in rows))
    base = [r[2]["search all"] for r in rows]
    for k in ("search locked", "search censored", "censored at floor"):
        d = paired_difference([r[2][k] for r in rows], base)
        print(f"  {k} - search all: {d.fmt()} m (90 %, over the six flights)")
    print("the label's held-out evidence behind the best candidate, nats (0: it leads):")
    for tag in ("all", "locked"):
        print(f"  {tag:16s} " + " ".join(f"{r[3][tag]:5.1f}" for r in rows))
    print_member_table([r[0] for r in rows], members)


if __name__ == "__main__":
    main()
