"""One causal attitude model of a multicopter, used by the fast simulator and the simulated MAVLink
vehicle.

Why one model: training data (``simulate``, via ``kinematics.attitude_from_motion``) and flown logs
(the vehicle in ``sitl/``) must have the same attitude dynamics.  Why causal: the vehicle computes
its attitude while flying and re-plans on every mode change, so it cannot look ahead; the fast
simulator uses the very same filters on whole arrays.  A chunk of any length (one sample: a step)
continues from an ``AttitudeState``, so running a flight in pieces equals running it at once
(``tests/test_kinematics.py`` checks this).

The model, per sample of period ``dt``:
- velocity and acceleration: first-order lags (time constant ``Kinematics.response_s``, exact
  discretisation ``alpha = 1 - exp(-dt / tau)``) of the position differences and of the smoothed
  velocity's differences;
- yaw: the course over ground (held while slower than 0.3 m/s, unwrapped) through a first-order lag
  of ``yaw_tau_s`` (about 90 deg per 1.5 s at the default 60 deg/s), or ``Kinematics.heading_deg``
  when set;
- roll/pitch: the horizontal acceleration the thrust must supply (smoothed acceleration plus drag
  against the air-relative velocity, ``drag_pitch_deg_per_mps``) over g, in the body frame, plus
  turbulence, clipped at the lean-angle limit.  Roll right-wing-down and pitch nose-up positive
  (MAVLink).
Wind gusts and turbulence are Ornstein-Uhlenbeck processes (``ou_process``), exact in discrete time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from mission.trajectory.multicopter import G, Kinematics

HOVER_SPEED_MPS = 0.3  # below this the course is held (the nose does not follow GPS jitter)


def tilt_from_acceleration(
    a_n: np.ndarray, a_e: np.ndarray, yaw: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(roll, pitch) in radians, unclipped, that tilt the thrust to give the horizontal acceleration
    (north, east) (m/s^2) at heading ``yaw``: the one place the multicopter's tilt is derived from
    its acceleration."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    pitch = -np.arctan2(a_n * cy + a_e * sy, G)  # nose down to accelerate forward
    roll = np.arctan2(-a_n * sy + a_e * cy, G)  # right wing down to accelerate right
    return roll, pitch


def lag_alpha(dt: float, tau: float) -> float:
    """Gain of a first-order lag of time constant ``tau`` sampled every ``dt`` (exact
    discretisation)."""
    return 1.0 - math.exp(-dt / tau) if tau > 0 else 1.0


def yaw_tau_s(kin: Kinematics) -> float:
    """Time constant of the yaw response: a 90 deg turn in about two of them at ``yaw_rate_dps``."""
    return max(kin.response_s, 0.25 * math.pi / math.radians(kin.yaw_rate_dps))


def _lag(x: np.ndarray, alpha: float, y0: np.ndarray) -> np.ndarray:
    """First-order lag ``y[k] = y[k-1] + alpha (x[k] - y[k-1])`` along axis 0, from ``y[-1] =
    y0``."""
    x = np.asarray(x, dtype=float)
    zi = ((1.0 - alpha) * np.asarray(y0, dtype=float))[None, ...]
    return lfilter([alpha], [1.0, alpha - 1.0], x, axis=0, zi=zi)[0]


def ou_process(white: np.ndarray, dt: float, tau: float, sigma: float, x0) -> np.ndarray:
    """Ornstein-Uhlenbeck samples (exact discretisation) driven by standard normals ``white`` (N,
    ...)."""
    a = math.exp(-dt / tau)
    x = np.asarray(white, dtype=float) * (sigma * math.sqrt(1.0 - a * a))
    zi = (a * np.asarray(x0, dtype=float))[None, ...]
    return lfilter([1.0], [1.0, -a], x, axis=0, zi=zi)[0]


@dataclass(frozen=True)
class AttitudeState:
    """Filter state after the last sample: previous position, smoothed velocity and acceleration
    (ENU), held course and yaw (unwrapped radians, clockwise from north)."""

    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    course: float
    yaw: float

    @staticmethod
    def at_rest(pos, yaw: float = 0.0) -> AttitudeState:
        """A vehicle standing at ``pos`` with its nose at ``yaw``."""
        z = np.zeros(3)
        return AttitudeState(
            np.asarray(pos, dtype=float).copy(), z, z.copy(), float(yaw), float(yaw)
        )


def run_attitude(
    pos: np.ndarray,
    dt: float,
    kin: Kinematics,
    state: AttitudeState,
    wind_en: np.ndarray | None = None,
    turbulence: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, AttitudeState]:
    """Roll, pitch, yaw (N, 3, radians, yaw in [0, 2 pi)), smoothed velocity (N, 3) and the new
    state for positions ``pos`` (N, 3, ENU) sampled every ``dt`` after ``state``.

    ``wind_en`` (N, 2) or (2,) is the wind (east, north, m/s); ``turbulence`` (N, 2) adds (pitch,
    roll) radians before the lean-angle clip.
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 3)
    n = len(pos)
    if n == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), state
    alpha = lag_alpha(dt, kin.response_s)
    d = np.diff(pos, axis=0, prepend=state.pos[None, :]) / dt
    vel = _lag(d, alpha, state.vel)
    acc = _lag(np.diff(vel, axis=0, prepend=state.vel[None, :]) / dt, alpha, state.acc)
    if kin.heading_deg is not None:  # fixed-heading flight: the nose never turns
        course = np.full(n, math.radians(kin.heading_deg))
        yaw = course.copy()
    else:
        moving = vel[:, 0] ** 2 + vel[:, 1] ** 2 > HOVER_SPEED_MPS**2
        raw = np.where(moving, np.arctan2(vel[:, 0], vel[:, 1]), np.nan)
        idx = np.where(moving, np.arange(n), -1)
        np.maximum.accumulate(idx, out=idx)  # forward fill: hold the last course while hovering
        held = np.where(idx >= 0, raw[np.maximum(idx, 0)], state.course)
        course = np.unwrap(np.concatenate([[state.course], held]))[1:]
        yaw = _lag(course, lag_alpha(dt, yaw_tau_s(kin)), np.float64(state.yaw))
    wind = np.zeros(2) if wind_en is None else np.asarray(wind_en, dtype=float)
    k_drag = math.tan(math.radians(kin.drag_pitch_deg_per_mps)) * G  # m/s^2 per m/s of airspeed
    a_e = acc[:, 0] + k_drag * (vel[:, 0] - wind[..., 0])
    a_n = acc[:, 1] + k_drag * (vel[:, 1] - wind[..., 1])
    roll, pitch = tilt_from_acceleration(a_n, a_e, yaw)
    if turbulence is not None:
        pitch = pitch + turbulence[:, 0]
        roll = roll + turbulence[:, 1]
    lim = math.radians(kin.max_tilt_deg)
    att = np.stack(
        [np.clip(roll, -lim, lim), np.clip(pitch, -lim, lim), np.mod(yaw, 2 * np.pi)], axis=-1
    )
    new = AttitudeState(
        pos[-1].copy(), vel[-1].copy(), acc[-1].copy(), float(course[-1]), float(yaw[-1])
    )
    return att, vel, new
