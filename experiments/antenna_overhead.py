"""What the real antennas do overhead: the RSS by elevation, and selfcal with a dipole alone.

Why: the spiral networks, trained on vertical dipoles, localize the AFAR flights about as well as
they localize copies of them drawn with dipoles and no random field, and fail on copies drawn with
the measured RM-WB1-DN pattern (mission/gap/README.md, "Predictive checks with the design held").
The measured pattern, as the family mounts it (UAV upside down, rover upright), is strongest
straight up and down; a pair of dipoles has its nulls there.  This script asks the real flights:
1. the RSS (locked samples, transmitter at the label) against a free-space distance law (20 dB per
   decade, its offset set on the 15-30 deg band), by the elevation at which the rover sees the UAV,
   per flight (``mission.gap.overhead.elevation_profile``), beside what the family's measured pair
   and a dipole pair add at those elevations
   (relative to 15-30 deg; the measured pattern averaged over azimuth);
2. selfcal with a single vertical-dipole hypothesis against today's hypotheses (in-sample residual
   rms picks among them), per flight, with the paired 90 % interval over the four flights whose
   transmitter lies inside the flown area;
3. selfcal's antenna chosen by held-out time blocks instead (``cv_rmse``: each hypothesis kind
   fitted on four of five contiguous chunks of the flight, the fifth's RSS predicted with the fitted
   position, antenna and offset), the kind with the lowest held-out rms then fitted on the whole
   flight, against today's, paired 90 % over the six flights.
Exploration: it decides nothing (six flights, two teams).

    python experiments/antenna_overhead.py --logs 'real/*.csv'      # imported AFAR flights, 30 s
"""

from __future__ import annotations

import argparse
import glob

import numpy as np

from experiments.receiver_lock import _subset as subset
from mission.cells import cell_average
from mission.evidence import paired_difference
from mission.flightlog import read_flight_log
from mission.gap.overhead import EL_BANDS_DEG, REF_BAND, elevation_profile
from mission.localize.api import _in_log_frame, search_area
from mission.localize.classical import as_flight
from mission.localize.methods import method_entry
from mission.localize.preprocess import select_samples
from mission.localize.selfcal import (
    HYPOTHESIS_KINDS,
    SelfCalibratingGrid,
    _geometry,
    antenna_hypotheses,
    hypothesis_residuals,
)
from mission.physics.antenna import Dipole, rm_wb1_dn

INSIDE = ("288_loc_1", "288_loc_2", "328_loc_1", "328_loc_2")  # transmitter inside the flown area


def expected_profiles() -> tuple[np.ndarray, np.ndarray]:
    """What the family's measured pair (rover upright, UAV upside down, azimuth-averaged) and a
    dipole pair add at each band's middle elevation, relative to ``REF_BAND``'s (dB)."""
    mid = np.radians(np.convolve(EL_BANDS_DEG, [0.5, 0.5], "valid"))
    az = np.radians(np.arange(0.0, 360.0, 10.0))
    pat = rm_wb1_dn()
    # the rover sees the UAV at +el; the UAV, upside down, sees the rover at -el in its body, i.e.
    # at +el of the flipped pattern: both ends read the upright pattern at +el
    meas = np.array([2.0 * np.mean(pat.gain_dbi(np.full(len(az), e), az)) for e in mid])
    dip = np.array([2.0 * float(Dipole().gain_dbi(e, 0.0)) for e in mid])
    return meas - meas[REF_BAND], dip - dip[REF_BAND]


def selfcal_errors(log) -> dict[str, tuple[float, float, str]]:
    """{today | dipole: (error m, residual rms dB, antenna)} of selfcal on the flight."""
    part, _ = select_samples(log)
    t = log.truth_enu
    out = {}
    for tag, kw in (("today", {}), ("dipole", {"hypotheses": ("dipole",)})):
        loc = SelfCalibratingGrid(area=search_area(log), **kw)
        e = _in_log_frame(loc, loc.predict(part), log.origin, method_entry("selfcal").frame)
        err = float(np.hypot(e.x_m - t[0], e.y_m - t[1]))
        out[tag] = (err, e.fit.residual_rms_db, e.fit.antenna)
    return out


def cv_rmse(log, kind: str, folds: int = 5) -> float:
    """Held-out rms (dB) of selfcal restricted to one hypothesis ``kind``: fitted on all but one of
    ``folds`` contiguous chunks of the selected samples, the left-out chunk's cells predicted at the
    fitted position with the fitted antenna and offset."""
    part, _ = select_samples(log)
    f = as_flight(part)
    chunk = np.arange(len(f.rss_dbm)) * folds // len(f.rss_dbm)
    sse, m = 0.0, 0
    for j in range(folds):
        loc = SelfCalibratingGrid(area=search_area(log), hypotheses=(kind,))
        est = loc.predict(subset(f, chunk != j))
        hyps = [h for h in antenna_hypotheses((kind,)) if h[0] == est.fit.antenna]
        cells = cell_average(subset(f, chunk == j), loc.cell_m, loc.altitude_gap_m)
        pg, el, az, el_uav = _geometry(np.array([[est.x_m, est.y_m]]), cells, loc.tx_height_m)
        y = cells.rss_dbm.astype(np.float32)[None, :]
        r = next(hypothesis_residuals(y - pg, el, az, hyps, None, el_uav))[0]
        sse += float(np.sum((r - est.fit.offset_db) ** 2))
        m += len(r)
    return float(np.sqrt(sse / m))


def held_out_choice(log) -> tuple[str, dict[str, float], float]:
    """(the kind with the lowest ``cv_rmse``, every kind's, selfcal's error with it alone)."""
    scores = {k: cv_rmse(log, k) for k in HYPOTHESIS_KINDS}
    best = min(scores, key=scores.__getitem__)
    loc = SelfCalibratingGrid(area=search_area(log), hypotheses=(best,))
    part, _ = select_samples(log)
    e = _in_log_frame(loc, loc.predict(part), log.origin, method_entry("selfcal").frame)
    t = log.truth_enu
    return best, scores, float(np.hypot(e.x_m - t[0], e.y_m - t[1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--logs", required=True, help="glob of imported AFAR logs (with truth)")
    args = ap.parse_args()
    paths = sorted(glob.glob(args.logs))
    if not paths:
        raise SystemExit(f"no logs match {args.logs}")
    logs = [read_flight_log(p) for p in paths]
    names = [p.rsplit("/", 1)[-1].replace("results_useful_ori_exp_", "")[:9] for p in paths]
    edges = zip(EL_BANDS_DEG[:-1], EL_BANDS_DEG[1:], strict=True)
    bands = "".join(f"{f'{a:.0f}-{b:.0f}':>8s}" for a, b in edges)
    print("RSS + 20 log10 d (dB), locked samples, 0 at 15-30 deg; samples under each")
    print(f"{'elevation deg':15s}{bands}")
    for name, log in zip(names, logs, strict=True):
        means, counts = elevation_profile(log)
        print(f"  {name:13s}" + "".join(f"{m:+8.1f}" for m in means))
        print(f"  {'':13s}" + "".join(f"{n:8d}" for n in counts))
    meas, dip = expected_profiles()
    print(f"  {'measured pair':13s}" + "".join(f"{x:+8.1f}" for x in meas))
    print(f"  {'dipole pair':13s}" + "".join(f"{x:+8.1f}" for x in dip))
    print("selfcal: error m (residual rms dB), today and with a single dipole")
    errs = {}
    for name, log in zip(names, logs, strict=True):
        s = selfcal_errors(log)
        errs[name] = s
        (a, ra, ant), (b, rb, _) = s["today"], s["dipole"]
        print(f"  {name} today {a:6.1f} ({ra:5.2f}) dipole {b:6.1f} ({rb:5.2f})")
        print(f"    today's antenna: {ant}")
    inside = [n for n in names if n in INSIDE]
    d = paired_difference(
        [errs[n]["dipole"][0] for n in inside], [errs[n]["today"][0] for n in inside]
    )
    print(f"  dipole - today, transmitter inside the flown area ({len(inside)}): {d.fmt()} m")
    print("selfcal's antenna kind chosen by held-out time blocks; held-out rms dB of")
    print("  " + " / ".join(HYPOTHESIS_KINDS))
    chosen = []
    for name, log in zip(names, logs, strict=True):
        best, scores, err = held_out_choice(log)
        chosen.append(err)
        rms = "/".join(f"{v:.1f}" for v in scores.values())
        print(f"  {name} {best:16s} {err:5.1f} m (today {errs[name]['today'][0]:5.1f}); {rms}")
    d = paired_difference(chosen, [errs[n]["today"][0] for n in names])
    print(f"  held-out choice - today, six flights: {d.fmt()} m")


if __name__ == "__main__":
    main()
