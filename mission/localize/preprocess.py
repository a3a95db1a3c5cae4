"""Keep the cruise part of a flight log: drop ground time, take-off, landing and climbs by altitude.

Rule (any trajectory, one or several cruise altitudes): let ``h`` be the height above the origin's
ground (ENU z, i.e. ``rel_alt_m``-like).  The *upper part* is the samples above half of the flight's
99th-percentile height; its median is the cruise altitude ``h_c``, and samples within ``band(h_c)``
(default ``max(3 m, 15 % of h_c)``) of it are the first cruise altitude's, when that band holds at
least half of the upper part and is centred on it (its samples' median within half a band).
Otherwise (a flight split between altitudes, whose median falls between them), and for every further
altitude, the altitude is the height whose band holds the most of the remaining airborne samples
(refined to their median); a further altitude is kept while its band holds at least
``min_altitude_share`` of the airborne samples and lies above ``min_cruise_m``.  Why cruise
altitudes and not "everything airborne": on the real AFAR flights climbs and descents are ~17 dB off
the model (``benchmarks/calibrate_real_afar.py``), while a second survey altitude is good data
(other teams flew at 20-47 m).  A flight that never leaves the ground (``h_c`` below
``min_cruise_m``) keeps everything, and says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mission.errors import InputError
from mission.flightlog import FLOWN_PHASES, PHASES


@dataclass
class CruiseSelection:
    """Which samples are cruise (``mask``), at what altitude (the first one) and band, and why;
    ``altitudes`` lists every kept cruise altitude as (altitude m, band m)."""

    mask: np.ndarray
    cruise_alt_m: float
    band_m: float
    reason: str
    altitudes: list[tuple[float, float]] = field(default_factory=list)

    @property
    def n_kept(self) -> int:
        return int(self.mask.sum())


def _band(h: np.ndarray | float, band_m: float | None) -> np.ndarray | float:
    """Half-width of a cruise altitude's band: ``band_m`` or max(3 m, 15 % of the altitude)."""
    return band_m if band_m is not None else np.maximum(3.0, 0.15 * np.asarray(h, dtype=float))


def _densest_altitude(hs: np.ndarray, lo: float, band_m: float | None) -> tuple[float, int]:
    """(altitude, count): the height in [lo, max] whose band holds the most of the sorted heights
    ``hs``, refined to the median of the heights in that band (vectorised over a 0.25 m grid of
    candidate altitudes)."""
    c = np.arange(lo, hs[-1] + 0.25, 0.25)
    b = _band(c, band_m)
    cnt = np.searchsorted(hs, c + b, "right") - np.searchsorted(hs, c - b, "left")
    k = int(np.argmax(cnt))
    bk = b[k] if np.ndim(b) else b
    inside = hs[np.abs(hs - c[k]) <= bk]
    return float(np.median(inside)), int(cnt[k])


def cruise_mask(
    height_m: np.ndarray,
    band_m: float | None = None,
    min_cruise_m: float = 5.0,
    min_altitude_share: float = 0.15,
    max_altitudes: int = 4,
) -> CruiseSelection:
    """Select the cruise part (one or more cruise altitudes) from heights above ground (N,) in
    metres."""
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
    airborne = h >= min_cruise_m
    n_air = int(airborne.sum())
    b = float(_band(hc, band_m))
    mask = np.abs(h - hc) <= b
    # split between altitudes: the median is no cruise altitude (its band holds under half of the
    # upper part, or it catches one altitude off-centre: the band's own samples sit over half a band
    # away from the median)
    if int(mask.sum()) < 0.5 * int(upper.sum()) or abs(float(np.median(h[mask])) - hc) > 0.5 * b:
        hc, _ = _densest_altitude(np.sort(h[airborne]), min_cruise_m, band_m)
        b = float(_band(hc, band_m))
        mask = np.abs(h - hc) <= b
    altitudes = [(hc, b)]
    while len(altitudes) < max_altitudes:
        rest = np.sort(h[airborne & ~mask])
        if rest.size < max(2, min_altitude_share * n_air):
            break
        lv, cnt = _densest_altitude(rest, min_cruise_m, band_m)
        bl = float(_band(lv, band_m))
        new = airborne & ~mask & (np.abs(h - lv) <= bl)
        if cnt < min_altitude_share * n_air or int(new.sum()) < min_altitude_share * n_air:
            break
        mask |= new
        altitudes.append((lv, bl))
    dropped = n - int(mask.sum())
    ground = int((h < min_cruise_m).sum())
    at = " and ".join(f"{lv:.1f} m +- {bl:.1f} m" for lv, bl in altitudes)
    reason = (
        f"cruise at {at}: kept {int(mask.sum())} of {n} samples, dropped {dropped} "
        f"(take-off, landing, off-altitude; {ground} below {min_cruise_m:g} m)"
    )
    return CruiseSelection(mask, altitudes[0][0], altitudes[0][1], reason, altitudes)


def select_cruise(log, band_m: float | None = None, min_cruise_m: float = 5.0):
    """(cruise part of a ``FlightLog``, ``CruiseSelection``); heights are the log's ENU z about its
    origin."""
    sel = cruise_mask(log.enu()[:, 2], band_m, min_cruise_m)
    return log.select(sel.mask), sel


def select_mission_legs(log):
    """(samples flown on mission legs, reason) when the log records the mission phase per row, else
    None.

    Why: the height band keeps any sample at cruise height, including a return leg flown at cruise
    height (nose-backwards on ArduPilot, 22-24 deg pitch); the runner's ``phase`` column says which
    rows were flown on the mission's own legs or on adaptive legs (``mission.flightlog.PHASES``).
    """
    phase = log.columns.get("phase")
    if phase is None:
        return None

    ph = np.asarray(phase).astype(str)
    if not np.isin(ph, PHASES).all():
        return None
    # the mission's own legs and those planned in flight (adaptive)
    mask = np.isin(ph, FLOWN_PHASES)
    if mask.sum() < 2:
        return None
    n = len(ph)
    return log.select(mask), f"mission legs (phase column): kept {int(mask.sum())} of {n} samples"


def select_samples(log):
    """The samples a localizer uses, and why: mission legs when the phase is logged, else the cruise
    altitudes."""
    legs = select_mission_legs(log)
    if legs is not None:
        return legs
    part, sel = select_cruise(log)
    # e.g. ``localize --at 0``: the vehicle was still on the ground (an IndexError before)
    if len(part) == 0:
        raise InputError(
            f"no samples to localize from ({sel.reason}); the flight had not reached its legs",
            source=str(log.path) if log.path else None,
        )
    return part, sel.reason
