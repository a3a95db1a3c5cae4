"""The simulated multicopter's limits and response (``Kinematics``) and gravity: the vocabulary that
the path planner (``kinematics``) and the attitude model (``attitude``) share, kept below both so
neither imports the other's module for it."""

from __future__ import annotations

from dataclasses import dataclass

G = 9.80665  # m/s^2


@dataclass(frozen=True)
class Kinematics:
    """Limits and response of the simulated multicopter (defaults: a small AERPAW-class
    quadcopter)."""

    cruise_speed_mps: float = 5.0
    accel_mps2: float = 1.5  # horizontal acceleration/deceleration limit
    climb_rate_mps: float = 2.5  # vertical speed (take-off, descent)
    corner_exponent: float = 2.0  # v_corner = v * cos(turn/2)**k
    yaw_rate_dps: float = 60.0  # yaw rate limit when turning to the new course
    response_s: float = 0.8  # time constant of the attitude response (smoothing of accelerations)
    drag_pitch_deg_per_mps: float = (
        0.6  # steady nose-down pitch per m/s of airspeed (real AFAR: ~-3 deg)
    )
    max_tilt_deg: float = 30.0  # lean-angle limit (ArduPilot default)
    heading_deg: float | None = (
        None  # None: yaw follows the course; a number: hold this compass heading
    )
