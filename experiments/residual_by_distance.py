"""Is the real residual quieter near the transmitter than the physics family draws it?

Why: stop 57 left a suspect for why the family's flights are about twice as hard to localize as the
real ones (mission/gap/README.md): the family sizes its shadowing to the real held-out residual
everywhere, so the model's misfit far from the transmitter (bands of -18 to +1 dB) would be drawn
as random shadowing near it too, where localization is decided.  This script measures the real
residual by horizontal distance to the label, on the samples the sounder read locked (the
residual of ``receiver_lock.label_residual``: the ``afar`` fold fitted without the flight's team),
and sets it beside the family's total residual standard deviation (shadowing and white noise, at
their means in ``mission/data/afar_family.json``).  Printed per flight and band: samples, mean and
standard deviation (dB); then the spread within 50 m against beyond 100 m over the flights that
have both, with a 90 % bootstrap interval over those flights.

    python experiments/residual_by_distance.py --mat ../shared/data/afar2023/mat     # ~20 s
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from experiments.receiver_lock import label_residual, quality_log
from mission.evidence import mean_interval, paired_difference
from mission.flightlog.schema import SOUNDER_LOCK_DB
from mission.localize.classical import as_flight
from mission.localize.preprocess import select_samples
from mission.physics.family import load_family

BANDS_M = (0.0, 50.0, 100.0, 150.0, 200.0, 300.0, 600.0)
NEAR_M, FAR_M = 50.0, 100.0


def bands(log) -> tuple[list[tuple[float, float, int, float, float]], float, float]:
    """(per band: lo, hi, samples, mean, sd; sd within ``NEAR_M``; sd beyond ``FAR_M``) of the
    flight's locked residual at the label (NaN where a band holds under 50 samples)."""
    part, _ = select_samples(log)
    r, _, locked = label_residual(log, part, SOUNDER_LOCK_DB)
    f = as_flight(part)
    d = np.hypot(*(f.enu_m[:, :2] - np.asarray(log.truth_enu[:2])).T)
    r, d = r[locked], d[locked]
    out = []
    for lo, hi in zip(BANDS_M[:-1], BANDS_M[1:], strict=True):
        m = (d >= lo) & (d < hi)
        ok = m.sum() >= 50
        out.append((lo, hi, int(m.sum()), *((r[m].mean(), r[m].std()) if ok else (np.nan,) * 2)))
    near, far = d < NEAR_M, d >= FAR_M
    sd_near = float(r[near].std()) if near.sum() >= 50 else float("nan")
    sd_far = float(r[far].std()) if far.sum() >= 50 else float("nan")
    return out, sd_near, sd_far


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--mat", required=True, help="folder of the AFAR 2023 .mat files")
    args = ap.parse_args()
    res = load_family("afar").residual
    fam = float(np.hypot(res["shadowing_db"]["mean"], res["noise_db"]["mean"]))
    near, far, names = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for mat in sorted(Path(args.mat).glob("*.mat")):
            name = mat.stem.replace("results_useful_ori_exp_", "")
            rows, sn, sf = bands(quality_log(mat, Path(tmp)))
            print(f"{name}: locked residual at the label by distance (m): n, mean, sd dB")
            for lo, hi, n, mu, sd in rows:
                print(f"  {lo:4.0f}-{hi:3.0f} {n:6d} {mu:+6.1f} {sd:5.1f}")
            if np.isfinite(sn) and np.isfinite(sf):
                near.append(sn)
                far.append(sf)
                names.append(name)
    print(f"family 'afar': total residual sd {fam:.1f} dB at every distance")
    print(f"flights with both: {', '.join(names)}")
    print(f"  sd within {NEAR_M:.0f} m  {mean_interval(near).fmt()} dB")
    print(f"  sd beyond {FAR_M:.0f} m {mean_interval(far).fmt()} dB")
    print(f"  near - far        {paired_difference(near, far).fmt()} dB")


if __name__ == "__main__":
    main()
