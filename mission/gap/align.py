"""Per-sample alignment: the geometry every candidate effect needs, computed once per flight.

Why: every breakdown of the residual (by distance, depression, body azimuth, world azimuth,
attitude, flight segment, position) and every candidate effect reads the same few geometric
quantities; computing them once, vectorised, keeps the diagnosis fast and makes the breakdown and
the effects agree on conventions (SPEC section 1, ``mission.physics.geometry``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.flightlog.schema import QUALITY_COLUMN, out_of_lock
from mission.importers.afar import AFAR2023_TRUTH, convert_afar_mat
from mission.physics.geometry import (
    bearing,
    body_angles,
    elevation,
    enu_to_ned,
    horizontal_distance,
    link_delta,
    slant_distance,
)
from mission.samples import FlightSamples

SEGMENTS = ("climb", "cruise", "turn", "descent")


@dataclass
class Alignment:
    """Per-sample geometry of one flight w.r.t. its transmitter (arrays of length N, angles in
    radians)."""

    d_h: np.ndarray  # horizontal distance UAV-transmitter (m)
    d_3d: np.ndarray  # direct-ray length (m)
    az_b: np.ndarray  # body azimuth of the transmitter, [0, 2 pi), 0 = nose, clockwise
    dep_b: np.ndarray  # body depression of the transmitter, positive below the body plane
    az_world: np.ndarray  # compass bearing of the UAV seen from the transmitter, [0, 2 pi)
    elev: np.ndarray  # elevation of the UAV seen from the transmitter (level frame)
    grazing: np.ndarray  # grazing angle of the ground-reflected ray (image method)
    tilt: np.ndarray  # attitude magnitude: angle between body z and the vertical
    segment: np.ndarray  # index into SEGMENTS (climb, cruise, turn, descent)
    x: np.ndarray  # UAV east (m)
    y: np.ndarray  # UAV north (m)
    h: np.ndarray  # UAV height (m)

    def as_dict(self) -> dict[str, np.ndarray]:
        """The binnable variables by name (angles in degrees, for people)."""
        return {
            "distance_m": self.d_h,
            "depression_deg": np.rad2deg(self.dep_b),
            "body_azimuth_deg": np.rad2deg(self.az_b),
            "world_azimuth_deg": np.rad2deg(self.az_world),
            "attitude_deg": np.rad2deg(self.tilt),
            "grazing_deg": np.rad2deg(self.grazing),
            "height_m": self.h,
        }


def flight_segment(
    t_s: np.ndarray,
    rx_enu: np.ndarray,
    yaw_rad: np.ndarray,
    vz_thresh: float = 0.7,
    turn_thresh_deg_s: float = 12.0,
    smooth_s: float = 1.0,
) -> np.ndarray:
    """Flight segment per sample (index into SEGMENTS): climb/descent by vertical speed, turn by yaw
    rate, else cruise.

    Rates are taken from telemetry smoothed over ``smooth_s`` (GPS heights are noisy at 30 Hz).
    """
    n = len(t_s)
    if n < 3:
        return np.full(n, 1, dtype=int)
    dt = float(np.median(np.diff(t_s))) or 0.03
    k = max(1, int(round(smooth_s / dt)))
    kern = np.ones(k) / k

    def smooth(a: np.ndarray) -> np.ndarray:
        pad = np.pad(a, (k // 2, k - 1 - k // 2), mode="edge")
        return np.convolve(pad, kern, mode="valid")

    vz = np.gradient(smooth(rx_enu[:, 2]), t_s)
    yaw_u = np.unwrap(yaw_rad)
    yaw_rate = np.rad2deg(np.abs(np.gradient(smooth(yaw_u), t_s)))
    seg = np.full(n, SEGMENTS.index("cruise"), dtype=int)
    seg[yaw_rate > turn_thresh_deg_s] = SEGMENTS.index("turn")
    seg[vz > vz_thresh] = SEGMENTS.index("climb")
    seg[vz < -vz_thresh] = SEGMENTS.index("descent")
    return seg


def align(flight: FlightSamples) -> Alignment:
    """Compute the per-sample geometry of ``flight`` (vectorised; it needs the truth and the
    attitude)."""
    rx = flight.enu_m
    tx = np.asarray(flight.tx_enu_m, dtype=float)
    att = flight.attitude_rad
    dx, dy, dz = link_delta(tx, rx)  # p_tx - p_uav (ENU)
    d_h = horizontal_distance(dx, dy)
    d_3d = slant_distance(dx, dy, dz)
    az_b, dep_b = body_angles(enu_to_ned(np.stack([dx, dy, dz], axis=-1)), att)
    az_world = bearing(-dx, -dy)
    h_t, h_r, d_2d = tx[2], rx[:, 2], np.maximum(d_h, 1e-9)
    elev = elevation(h_r - h_t, d_2d)
    grazing = elevation(h_r + h_t, d_2d)  # grazing angle psi, as in PropagationModel.explain
    tilt = np.arccos(np.clip(np.cos(att[:, 0]) * np.cos(att[:, 1]), -1.0, 1.0))
    seg = flight_segment(flight.t_s, rx, att[:, 2])
    return Alignment(
        d_h, d_3d, az_b, dep_b, az_world, elev, grazing, tilt, seg, rx[:, 0], rx[:, 1], rx[:, 2]
    )


def flight_from_log(
    log, tx_enu: np.ndarray | None = None, name: str | None = None
) -> FlightSamples:
    """A ``mission.flightlog.FlightLog``'s samples ready for diagnosis: truth from the sidecar
    unless given, attitude required (NaN read as 0), samples without RSS dropped, named after the
    file's stem."""
    src = str(log.path) if log.path is not None else (name or "log")
    tx = tx_enu if tx_enu is not None else log.truth_enu
    if tx is None:
        raise InputError(
            "no transmitter truth: give --truth LAT,LON or a sidecar with 'truth'", source=src
        )
    s = log.samples()
    if s.attitude_rad is None:
        raise InputError(
            "the log has no attitude (roll/pitch/yaw); the gap diagnosis needs it", source=src
        )
    nm = name or (log.path.stem if log.path is not None else "flight")
    f = replace(
        s,
        attitude_rad=np.where(np.isnan(s.attitude_rad), 0.0, s.attitude_rad),
        tx_enu_m=np.asarray(tx, dtype=float),
        name=nm,
    )
    return f.select(np.isfinite(f.rss_dbm))


def locked_rows(log, lock_db: float):
    """The rows of ``log`` whose receiver quality ``rss_quality_db`` is at least ``lock_db``: what a
    diagnosis keeps when told which samples were read with the receiver's lock lost (a missing
    quality, NaN, counts as not locked).  A log without the column is an ``InputError``: nothing
    says which of its samples to trust."""
    if QUALITY_COLUMN not in log.columns:
        raise InputError(
            f"has no {QUALITY_COLUMN} column: nothing says which samples were read locked",
            source=str(log.path) if log.path is not None else None,
            field="--lock",
        )
    return log.select(~out_of_lock(log[QUALITY_COLUMN], lock_db))


def afar2023_flights(
    mat_dir, min_height_m: float = 10.0, lock_db: float | None = None
) -> list[FlightSamples]:
    """The six AFAR 2023 challenge flights (teams 288, 328; rover locations 1-3) with their rover
    truth, airborne samples only; named ``<team>-loc<n>``.  Used by the real-flight benchmark
    scripts.  ``lock_db``: keep only the samples whose sounder quality (``mquality``, the import's
    ``rss_quality_db``) is at least this, i.e. withhold those read while the sounder had lost lock
    (``experiments/receiver_lock.py``)."""
    out = []
    for team in (288, 328):
        for loc in (1, 2, 3):
            res = convert_afar_mat(
                Path(mat_dir) / f"results_useful_ori_exp_{team}_loc_{loc}.mat", AFAR2023_TRUTH[loc]
            )
            log = res.log if lock_db is None else locked_rows(res.log, lock_db)
            f = flight_from_log(log, name=f"{team}-loc{loc}")
            out.append(f.select(f.enu_m[:, 2] > min_height_m))
    return out
