"""Fast flight simulator: fly a waypoint path kinematically and sample RSS through a propagation
model.

No MAVLink is involved: dataset generation, previews and tests use this.  The vehicle follows
``trajectory.kinematics`` (speed/acceleration limits, yaw along the track, roll/pitch from the
commanded accelerations) plus a random attitude perturbation (uniform in [-5, 5] deg per sample by
default, as in the paper's training data), and RSS is sampled every ``dt`` = 0.03 s with Gaussian
noise (1 dB by default). Optionally (``shadowing_db`` > 0) a spatially correlated log-normal
shadowing field is added: real flights depart from any deterministic model by errors that persist
over tens of metres (buildings, trees, the vehicle's own body), not by white noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from mission.flightlog import LAND, MISSION, RETURN, TAKEOFF
from mission.geo import Origin
from mission.physics.shadowing import shadowing_field  # noqa: F401  (its home; re-exported)
from mission.samples import FlightSamples
from mission.trajectory.kinematics import (
    FlightProfile,
    Kinematics,
    attitude_from_motion,
    plan_profile,
)


@dataclass(frozen=True)
class SimConfig:
    """Sampling, perturbation and noise settings of a simulated flight."""

    dt_s: float = 0.03
    attitude_perturbation_deg: float = 5.0  # half-width of the uniform roll/pitch/yaw perturbation
    perturbation_corr_s: float = 0.0  # 0: independent per sample (paper); >0: smoothed (gust-like)
    noise_db: float = 1.0  # Gaussian RSS noise standard deviation
    rss_offset_db: float = 0.0  # constant receiver offset (uncalibrated real receivers)
    shadowing_db: float = 0.0  # std of the spatially correlated shadowing field (0: none)
    shadowing_corr_m: float = 30.0  # its correlation distance (correlation 1/e at this distance)
    kinematics: Kinematics = field(default_factory=Kinematics)


@dataclass
class SimulatedFlight(FlightSamples):
    """A simulated flight: its ``FlightSamples`` (with the true transmitter and the phase) and the
    flight profile it was sampled from (for the phase, the path length, the duration)."""

    profile: FlightProfile | None = None

    def log_columns(self, origin: Origin) -> dict[str, np.ndarray]:
        """Columns of the flight-log CSV (see ``mission.flightlog``)."""
        lat, lon, alt = origin.to_geodetic(self.enu_m)
        att = np.rad2deg(self.attitude_rad)
        phase, item = path_phases(self.profile, self.t_s)
        return {
            "t_s": self.t_s,
            "lat_deg": lat,
            "lon_deg": lon,
            "alt_m": alt,
            "rel_alt_m": self.enu_m[:, 2],
            "roll_deg": att[:, 0],
            "pitch_deg": att[:, 1],
            "yaw_deg": att[:, 2],
            "rss_dbm": self.rss_dbm,
            "phase": phase,
            "mission_item": item,
        }


def leg_phases(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mission phase (``flightlog.PHASES``) and mission item (K-1,) of each leg of a path (K, 3)
    shaped as ``MissionSpec.flight_path_enu`` builds it: leading climbing vertical legs are the
    take-off, trailing descending vertical legs the landing, a horizontal leg back over the start
    just before the landing the return, the rest the mission (item k: flying to waypoint k; a path
    without take-off starts at waypoint 0).

    A planned path's phases from its geometry; a flown vehicle's come from its events instead
    (``flight.phases.PhaseTracker``), with the same names and item rule.
    """
    vertices = np.asarray(vertices, dtype=float)
    d = np.diff(vertices, axis=0)
    vertical = np.linalg.norm(d[:, :2], axis=1) < 1e-6
    n = len(d)
    n_up = int(np.argmin(vertical & (d[:, 2] > 0))) if not np.all(vertical & (d[:, 2] > 0)) else n
    down = (vertical & (d[:, 2] < 0))[::-1]
    n_down = int(np.argmin(down)) if not np.all(down) else n
    name = np.full(n, MISSION, dtype=object)
    name[:n_up] = TAKEOFF
    name[n - n_down :] = LAND
    last = n - n_down - 1  # the leg before the landing
    back = np.linalg.norm(vertices[last + 1, :2] - vertices[0, :2]) < 1.0
    if n_up and last > n_up and back:
        name[last] = RETURN
    first_wp = n_up + 1 if n_up else 0
    return name, np.where(name == MISSION, np.arange(n) + 1 - first_wp, -1)


def path_phases(profile: FlightProfile, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mission phase and mission item at times ``t`` along ``profile`` (its legs'
    ``leg_phases``)."""
    name, item = leg_phases(profile.vertices)
    leg = np.clip(np.searchsorted(profile.t_vertex, t, side="right") - 1, 0, len(name) - 1)
    return name[leg].astype(str), item[leg]


def fly_path(
    waypoints_enu: np.ndarray,
    cfg: SimConfig,
    rng: np.random.Generator,
    profile: FlightProfile | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, FlightProfile]:
    """Times, positions and perturbed attitudes of a kinematic flight through ``waypoints_enu``."""
    profile = profile or plan_profile(waypoints_enu, cfg.kinematics)
    t, pos = profile.sample(cfg.dt_s)
    att, _ = attitude_from_motion(t, pos, cfg.kinematics)
    att = att + perturbation(len(t), cfg, rng)
    att[:, 2] = np.mod(att[:, 2], 2 * np.pi)
    return t, pos, att, profile


def perturbation(n: int, cfg: SimConfig, rng: np.random.Generator) -> np.ndarray:
    """Random roll/pitch/yaw perturbation (n, 3) radians, uniform in
    +-``attitude_perturbation_deg``."""
    w = np.deg2rad(cfg.attitude_perturbation_deg)
    p = rng.uniform(-w, w, size=(n, 3))
    if cfg.perturbation_corr_s > 0 and n > 1:
        sigma = cfg.perturbation_corr_s / cfg.dt_s
        p = gaussian_filter1d(p, sigma, axis=0, mode="wrap")
        p *= w / np.maximum(np.max(np.abs(p), axis=0), 1e-12)  # keep the configured range
    return p


def simulate_flight(
    waypoints_enu: np.ndarray,
    tx_enu: np.ndarray,
    model,
    cfg: SimConfig | None = None,
    rng: np.random.Generator | None = None,
    profile: FlightProfile | None = None,
) -> SimulatedFlight:
    """Fly ``waypoints_enu`` and sample RSS from a transmitter at ``tx_enu`` (3,) through ``model``.

    ``model`` is a ``mission.physics`` propagation model (``rss_dbm(tx, rx, attitude)``).  Draw
    order is fixed (attitude perturbation, then noise) so a seed reproduces the same bytes.
    """
    cfg = cfg or SimConfig()
    rng = rng if rng is not None else np.random.default_rng(0)
    t, pos, att, profile = fly_path(waypoints_enu, cfg, rng, profile)
    tx = np.asarray(tx_enu, dtype=float)
    rss = np.asarray(model.rss_dbm(tx, pos, att), dtype=float)
    rss = rss + cfg.rss_offset_db + rng.normal(0.0, cfg.noise_db, size=rss.shape)
    if cfg.shadowing_db > 0:  # drawn last, so flights without shadowing keep their bytes
        rss = rss + shadowing_field(pos[:, :2], cfg.shadowing_db, cfg.shadowing_corr_m, rng)
    return SimulatedFlight(
        enu_m=pos,
        rss_dbm=rss,
        attitude_rad=att,
        t_s=t,
        phase=path_phases(profile, t)[0],
        tx_enu_m=tx,
        profile=profile,
    )
