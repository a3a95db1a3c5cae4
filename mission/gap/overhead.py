"""The real RSS by elevation: what the two antennas add, read off a flight with a known transmitter.

Why: the physics family mounts the measured RM-WB1-DN pattern at both ends, strongest straight up
and down; the real flights fall 7-16 dB straight above the transmitter (mission/gap/README.md,
"What the antennas do overhead").  ``elevation_profile`` is that reading: the samples the receiver
read locked, plus the free-space path gain ``20 log10 d``, averaged in bands of the elevation at
which the transmitter sees the UAV, with the 15-30 degree band's mean set to 0 (so the offset and
the receiver's scale drop out).
"""

from __future__ import annotations

import numpy as np

from mission.flightlog.schema import QUALITY_COLUMN, out_of_lock
from mission.localize.preprocess import select_samples
from mission.physics.geometry import elevation, horizontal_distance, slant_distance

EL_BANDS_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)
REF_BAND = 1  # 15-30 deg: the band whose mean is set to 0
MIN_SAMPLES = 30  # a band with fewer reads NaN


def elevation_profile(log, tx_height_m: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """(mean dB, samples) per band of ``EL_BANDS_DEG`` of ``log``'s selected samples: RSS plus
    ``20 log10 d`` to its transmitter (``log.truth_enu``), the 15-30 degree band's mean set to 0;
    samples read out of lock are left out when the log says which.  NaN where a band holds fewer
    than ``MIN_SAMPLES`` (all NaN without any in the reference band)."""
    part, _ = select_samples(log)
    enu, t = part.enu(), np.asarray(log.truth_enu, dtype=float)
    p = np.asarray(part["rss_dbm"], dtype=float)
    keep = np.isfinite(p)
    if QUALITY_COLUMN in part.columns:
        keep &= ~out_of_lock(part[QUALITY_COLUMN])
    dx, dy, dz = (enu[:, k] - c for k, c in enumerate((t[0], t[1], tx_height_m)))
    dh = horizontal_distance(dx, dy)
    el = np.degrees(elevation(dz, dh))
    r = p + 20.0 * np.log10(np.maximum(slant_distance(dx, dy, dz), 1e-3))
    band = np.digitize(el, EL_BANDS_DEG[1:-1])
    n = np.array([int((keep & (band == b)).sum()) for b in range(len(EL_BANDS_DEG) - 1)])
    means = np.array(
        [
            float(np.mean(r[keep & (band == b)])) if n[b] >= MIN_SAMPLES else np.nan
            for b in range(len(n))
        ]
    )
    return means - means[REF_BAND], n
