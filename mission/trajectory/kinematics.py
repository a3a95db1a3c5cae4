"""Multicopter kinematics: how a waypoint path is flown in time, and the attitude that results.

One model serves the fast simulator, the mission time-budget check and the simulated MAVLink
vehicle, so that all three agree on how long a mission takes.  The path is the polyline through the
waypoints; along it the speed follows a trapezoidal profile per leg (acceleration limit
``accel_mps2``) with a corner speed that falls with the turn angle (``v_corner = v_cruise *
cos(turn/2) ** corner_exponent``, 0 for a reversal), as a PX4/ArduPilot waypoint controller slows
for corners.  Attitude follows from the accelerations (``attitude_from_motion``, on the causal model
of ``mission.trajectory.attitude`` that the simulated vehicle shares): a multicopter tilts its
thrust vector to accelerate, pitches nose-down against drag in steady forward flight, and yaws to
the direction of travel (or, with ``heading_deg``, holds one compass heading throughout, as the
AERPAW AFAR 2023 vehicles did: their logged yaw stays within about 30 deg of 330-360 deg for the
whole cruise).  Everything is vectorised over time samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mission.trajectory.attitude import AttitudeState, run_attitude
from mission.trajectory.multicopter import G, Kinematics

__all__ = [
    "G",
    "Kinematics",
    "FlightProfile",
    "plan_profile",
    "initial_course",
    "attitude_from_motion",
]


@dataclass
class FlightProfile:
    """A planned flight of a polyline: cumulative arc length per vertex and the speed profile per
    leg."""

    vertices: np.ndarray  # (K, 3) ENU
    s_vertex: np.ndarray  # (K,) arc length at each vertex
    t_vertex: np.ndarray  # (K,) time at each vertex
    v_vertex: np.ndarray  # (K,) speed at each vertex
    v_cruise: np.ndarray  # (K-1,) cruise speed per leg
    accel: float

    @property
    def duration_s(self) -> float:
        return float(self.t_vertex[-1])

    @property
    def length_m(self) -> float:
        return float(self.s_vertex[-1])

    def arclength(self, t) -> np.ndarray:
        """Arc length flown at times ``t`` (vectorised closed form of the per-leg trapezoid)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration_s)
        i = np.clip(np.searchsorted(self.t_vertex, t, side="right") - 1, 0, len(self.t_vertex) - 2)
        tau = t - self.t_vertex[i]
        v0, v1, vc, a = self.v_vertex[i], self.v_vertex[i + 1], self.v_cruise[i], self.accel
        L = self.s_vertex[i + 1] - self.s_vertex[i]
        vp = _peak_speed(L, v0, v1, vc, a)
        t_acc = (vp - v0) / a
        t_dec = (vp - v1) / a
        s_acc = (v0 + vp) / 2 * t_acc
        s_dec = (vp + v1) / 2 * t_dec
        t_cru = np.where(vp > 0, (L - s_acc - s_dec) / np.maximum(vp, 1e-9), 0.0)
        s = np.where(
            tau < t_acc,
            v0 * tau + 0.5 * a * tau**2,
            np.where(
                tau < t_acc + t_cru,
                s_acc + vp * (tau - t_acc),
                s_acc
                + vp * t_cru
                + vp * (tau - t_acc - t_cru)
                - 0.5 * a * (tau - t_acc - t_cru) ** 2,
            ),
        )
        return self.s_vertex[i] + np.clip(s, 0.0, L)

    def position(self, t) -> np.ndarray:
        """ENU positions (N, 3) at times ``t``."""
        s = self.arclength(t)
        j = np.clip(np.searchsorted(self.s_vertex, s, side="right") - 1, 0, len(self.s_vertex) - 2)
        seg = self.s_vertex[j + 1] - self.s_vertex[j]
        f = np.where(seg > 0, (s - self.s_vertex[j]) / np.where(seg > 0, seg, 1.0), 0.0)
        return self.vertices[j] + f[:, None] * (self.vertices[j + 1] - self.vertices[j])

    def sample(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Times every ``dt`` seconds over the whole flight, and the positions there."""
        t = np.arange(0.0, self.duration_s + 1e-9, dt)
        return t, self.position(t)


def _peak_speed(L, v0, v1, vc, a):
    """Highest speed reachable on a leg of length L from v0 to v1 under cruise vc and accel a."""
    vp_tri = np.sqrt(np.maximum((2 * a * L + v0**2 + v1**2) / 2, 0.0))
    return np.maximum(np.minimum(vc, vp_tri), np.maximum(v0, v1))


def _leg_time(L, v0, v1, vc, a):
    vp = _peak_speed(L, v0, v1, vc, a)
    t_acc, t_dec = (vp - v0) / a, (vp - v1) / a
    s_rest = L - (v0 + vp) / 2 * t_acc - (vp + v1) / 2 * t_dec
    return t_acc + t_dec + np.where(vp > 0, np.maximum(s_rest, 0) / np.maximum(vp, 1e-9), 0.0)


def plan_profile(
    waypoints: np.ndarray, kin: Kinematics | None = None, speeds: np.ndarray | None = None
) -> FlightProfile:
    """Plan the timed flight of the polyline ``waypoints`` (K, 3) ENU, starting and ending at rest.

    Vertical legs (take-off, landing) use the climb rate as their cruise speed.  ``speeds``
    optionally gives a cruise speed per leg (K-1,).
    """
    kin = kin or Kinematics()
    P = np.asarray(waypoints, dtype=float)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-6])
    P = P[keep]
    if len(P) < 2:
        z = np.zeros(1)
        return FlightProfile(
            P[:1].repeat(2, 0), np.zeros(2), np.zeros(2), np.zeros(2), z, kin.accel_mps2
        )
    d = np.diff(P, axis=0)
    L = np.linalg.norm(d, axis=1)
    horiz = np.linalg.norm(d[:, :2], axis=1)
    vert_frac = np.abs(d[:, 2]) / np.maximum(L, 1e-9)
    vc = (
        np.where(vert_frac > 0.7, kin.climb_rate_mps, kin.cruise_speed_mps)
        if speeds is None
        else np.asarray(speeds, dtype=float)
    )
    u = d / L[:, None]
    cos_turn = np.clip(np.sum(u[:-1] * u[1:], axis=1), -1.0, 1.0)
    turn = np.arccos(cos_turn)
    v_corner = np.minimum(vc[:-1], vc[1:]) * np.cos(turn / 2) ** kin.corner_exponent
    v_corner[(horiz[:-1] < 1e-6) | (horiz[1:] < 1e-6)] = (
        0.0  # stop between vertical and horizontal legs
    )
    v = np.concatenate([[0.0], v_corner, [0.0]])
    a = kin.accel_mps2
    # Enforce reachability: forward then backward pass so every leg can brake/accelerate in time.
    for i in range(len(L)):  # per waypoint (not per sample): K is small
        v[i + 1] = min(v[i + 1], np.sqrt(v[i] ** 2 + 2 * a * L[i]))
    for i in range(len(L) - 1, -1, -1):
        v[i] = min(v[i], np.sqrt(v[i + 1] ** 2 + 2 * a * L[i]))
    t_leg = _leg_time(L, v[:-1], v[1:], vc, a)
    s = np.concatenate([[0.0], np.cumsum(L)])
    t = np.concatenate([[0.0], np.cumsum(t_leg)])
    return FlightProfile(P, s, t, v, vc, a)


def initial_course(pos: np.ndarray, min_move_m: float = 0.5) -> float:
    """Course (radians, clockwise from north) of the first horizontal move of a path; 0 if it never
    moves."""
    d = np.asarray(pos, dtype=float)[:, :2] - np.asarray(pos, dtype=float)[0, :2]
    far = np.hypot(d[:, 0], d[:, 1]) > min_move_m
    if not far.any():
        return 0.0
    e, n = d[int(np.argmax(far))]
    return float(np.arctan2(e, n))


def attitude_from_motion(
    t: np.ndarray, pos: np.ndarray, kin: Kinematics | None = None, wind_ne: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Roll, pitch, yaw (N, 3, radians, MAVLink convention) and smoothed ENU velocity (N, 3) for a
    path sampled at (uniform) times ``t``, from rest with the nose along the first course.

    The model is ``mission.trajectory.attitude.run_attitude``, the one the simulated vehicle flies
    with: causal first-order lags of velocity and acceleration, yaw following the course (or
    ``kin.heading_deg``), tilt from the commanded acceleration plus drag against the air-relative
    velocity.  ``wind_ne`` is the wind (north, east) in m/s, (2,) or (N, 2).
    """
    kin = kin or Kinematics()
    pos = np.asarray(pos, dtype=float)
    if len(t) < 2:
        return np.zeros((len(t), 3)), np.zeros_like(pos)
    dt = float(np.median(np.diff(t)))
    wind_en = None if wind_ne is None else np.asarray(wind_ne, dtype=float)[..., [1, 0]]
    state = AttitudeState.at_rest(pos[0], initial_course(pos))
    att, vel, _ = run_attitude(pos, dt, kin, state, wind_en)
    return att, vel
