"""Keep the cruise part of a flight log: drop ground time, take-off, landing and low hovers by altitude.

Rule (any cruise altitude, any trajectory): let ``h`` be the height above the origin's ground (ENU z,
i.e. ``rel_alt_m``-like).  The *upper part* is the samples above half of the flight's 99th-percentile
height; its median is the cruise altitude ``h_c``.  Samples within ``band_m`` (default
``max(3 m, 15 % of h_c)``) of ``h_c`` are kept; everything else (on the ground, climbing, descending,
hovering at a low altitude) is dropped.  A flight that never leaves the ground (``h_c`` below
``min_cruise_m``) keeps everything, and says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class CruiseSelection:
    """Which samples are cruise (``mask``), at what altitude, and why."""

    mask: np.ndarray
    cruise_alt_m: float
    band_m: float
    reason: str

    @property
    def n_kept(self) -> int:
        return int(self.mask.sum())


def cruise_mask(
    height_m: np.ndarray, band_m: float | None = None, min_cruise_m: float = 5.0
) -> CruiseSelection:
    """Select the cruise part from heights above ground (N,) in metres."""
    h = np.asarray(height_m, dtype=float)
    n = h.size
    if n == 0:
        return CruiseSelection(np.zeros(0, dtype=bool), float("nan"), 0.0, "empty log")
    top = np.percentile(h, 99)
    upper = h >= 0.5 * top
    hc = float(np.median(h[upper]))
    if hc < min_cruise_m:
        return CruiseSelection(
            np.ones(n, dtype=bool),
            hc,
            float("inf"),
            f"no cruise above {min_cruise_m:g} m found (median upper height {hc:.1f} m): kept all",
        )
    band = float(band_m) if band_m is not None else max(3.0, 0.15 * hc)
    mask = np.abs(h - hc) <= band
    dropped = n - int(mask.sum())
    ground = int((h < min_cruise_m).sum())
    reason = (
        f"cruise at {hc:.1f} m +- {band:.1f} m: kept {int(mask.sum())} of {n} samples, dropped {dropped} "
        f"(take-off, landing, off-altitude; {ground} below {min_cruise_m:g} m)"
    )
    return CruiseSelection(mask, hc, band, reason)


def select_cruise(log, band_m: float | None = None, min_cruise_m: float = 5.0):
    """(cruise part of a ``FlightLog``, ``CruiseSelection``); heights are the log's ENU z about its origin."""
    sel = cruise_mask(log.enu()[:, 2], band_m, min_cruise_m)
    return log.select(sel.mask), sel


def select_mission_legs(log):
    """(samples flown on mission legs, reason) when the log records the mission phase per row, else None.

    Why: the height band keeps any sample at cruise height, including a return leg flown at cruise height
    (nose-backwards on ArduPilot, 22-24 deg pitch); the runner's ``phase`` column says which rows were flown
    on the mission's own legs (``mission.flightlog.PHASES``).
    """
    phase = log.columns.get("phase")
    if phase is None:
        return None
    from mission.flightlog import PHASES

    ph = np.asarray(phase).astype(str)
    if not np.isin(ph, PHASES).all():
        return None
    mask = ph == "mission"
    if mask.sum() < 2:
        return None
    n = len(ph)
    return log.select(mask), f"mission legs (phase column): kept {int(mask.sum())} of {n} samples"


def select_samples(log):
    """The samples a localizer uses, and why: mission legs when the phase is logged, else the cruise height band."""
    legs = select_mission_legs(log)
    if legs is not None:
        return legs
    part, sel = select_cruise(log)
    return part, sel.reason
