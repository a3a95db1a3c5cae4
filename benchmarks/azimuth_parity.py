"""How much of the six real flights' held-out residual follows the rover's body azimuth, split into
the odd harmonics (1 and 3: louder on one side of the transmitter, which moves the RSS peak) and the
even ones (2 and 4: symmetric about it), fitted together with the time drift's basis.

    python benchmarks/azimuth_parity.py          # ~20 s on 2 cores, needs ../shared

The figures and what they say: mission/gap/README.md, "A pattern fixed to the body".
"""

from __future__ import annotations

import json
import sys

import numpy as np
from bench_gap import MAT, REPO, afar2023_flights  # this folder: run as a script

from mission.gap.diagnose import decimate_flight
from mission.gap.familyfit import MIN_HEIGHT_M, effects_of_ladder, fit_family
from mission.gap.fit import FitConfig
from mission.gap.temporal import time_columns
from mission.physics.family import azimuth_coordinate

COND_MAX = 1e3  # above it the split between the bases is not determined by the data


def parts_db(flight, held: np.ndarray) -> tuple[float, float, float]:
    """Std (dB) of the time drift's, the odd harmonics' and the even harmonics' parts of the
    held-out residual ``held``, fitted together (each column about its mean); NaN where the bases
    are nearly collinear on the flight's track."""
    ok = np.isfinite(held)
    t = np.asarray(flight.t_s, dtype=float)
    az = azimuth_coordinate(flight.tx_enu_m, flight.enu_m[ok], flight.attitude_rad[ok])[:, None]
    blocks = [
        time_columns(t[ok], float(t[0]), float(t[-1]), np.zeros(0))[0],
        np.column_stack([np.cos(az * [1, 3]), np.sin(az * [1, 3])]),
        np.column_stack([np.cos(az * [2, 4]), np.sin(az * [2, 4])]),
    ]
    blocks = [b - b.mean(axis=0) for b in blocks]
    X = np.column_stack(blocks)
    if np.linalg.cond(X) > COND_MAX:  # the bases nearly collinear on this track: no split
        return float("nan"), float("nan"), float("nan")
    coef, *_ = np.linalg.lstsq(X, held[ok] - held[ok].mean(), rcond=None)
    out, j = [], 0
    for b in blocks:
        out.append(float(np.std(b @ coef[j : j + b.shape[1]])))
        j += b.shape[1]
    return out[0], out[1], out[2]


def main() -> int:
    if not MAT.is_dir():
        print(f"no AFAR data at {MAT}", file=sys.stderr)
        return 2
    cfg = FitConfig(split="flights", loss="soft_l1", seed=0, rate_hz=3.0, processes=2)
    shipped = json.loads((REPO / "mission" / "data" / "afar_family.json").read_text())
    flights = [decimate_flight(f, cfg.rate_hz) for f in afar2023_flights(MAT)]
    effects, _ = effects_of_ladder(shipped["ladder"])
    _, fits = fit_family(flights, effects, cfg, seed=0, structure=("time", "azimuth"))
    print("flight          time  odd  even dB   (held-out residual std)")
    for f, fit in zip(flights, fits, strict=True):
        air = f.enu_m[:, 2] > MIN_HEIGHT_M
        f = f.select(air) if air.sum() > 200 else f  # the samples the fit used
        tm, odd, even = parts_db(f, fit.heldout)
        note = " (excluded from the family)" if fit.excluded else ""
        print(
            f"{fit.name:14s} {tm:5.1f} {odd:5.1f} {even:5.1f}    ({np.nanstd(fit.heldout):.1f})"
            f"{note}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
