"""Multicopter kinematics: limits respected, closed-form leg times, attitude signs and magnitudes."""

from __future__ import annotations

import numpy as np
import pytest

from mission.trajectory.kinematics import Kinematics, attitude_from_motion, plan_profile


def test_single_leg_closed_form_time():
    kin = Kinematics(cruise_speed_mps=5.0, accel_mps2=1.0)
    p = plan_profile(np.array([[0, 0, 30], [100, 0, 30]]), kin)
    # accelerate 5 s (12.5 m), cruise 75 m (15 s), brake 5 s: 25 s
    assert p.duration_s == pytest.approx(25.0)
    assert p.position(np.array([2.0]))[0, 0] == pytest.approx(0.5 * 1.0 * 4.0)
    assert p.position(np.array([25.0]))[0, 0] == pytest.approx(100.0)


def test_short_leg_is_triangular():
    kin = Kinematics(cruise_speed_mps=10.0, accel_mps2=1.0)
    p = plan_profile(np.array([[0, 0, 30], [16, 0, 30]]), kin)
    # peak speed sqrt(a L) = 4 m/s, time 2 * 4 s
    assert p.duration_s == pytest.approx(8.0)


def test_speed_and_acceleration_limits_hold():
    kin = Kinematics(cruise_speed_mps=6.0, accel_mps2=1.5)
    wp = np.array([[0, 0, 0], [0, 0, 30], [120, 0, 30], [120, 80, 30], [-40, 80, 30], [0, 0, 30], [0, 0, 0]])
    p = plan_profile(wp, kin)
    t, pos = p.sample(0.01)
    v = np.linalg.norm(np.diff(pos, axis=0), axis=1) / 0.01
    assert v.max() <= 6.0 + 1e-6
    s = p.arclength(t)
    ds = np.diff(s) / 0.01
    acc = np.diff(ds) / 0.01
    assert np.abs(acc).max() <= 1.5 * 1.05
    assert np.all(np.diff(s) >= -1e-9)
    assert np.allclose(p.position(np.array([p.duration_s]))[0], wp[-1], atol=1e-9)
    assert np.linalg.norm(pos[-1] - wp[-1]) < 0.01


def test_corners_slow_down_and_reversal_stops():
    kin = Kinematics(cruise_speed_mps=5.0, accel_mps2=1.5)
    p = plan_profile(np.array([[0, 0, 30], [100, 0, 30], [100, 100, 30], [100, 0, 30]]), kin)
    assert 0 < p.v_vertex[1] < 5.0          # 90 deg corner: cos(45)^2 * 5 = 2.5 m/s
    assert p.v_vertex[1] == pytest.approx(2.5)
    assert p.v_vertex[2] == pytest.approx(0.0, abs=1e-9)  # 180 deg reversal


def test_attitude_follows_motion():
    kin = Kinematics(cruise_speed_mps=5.0)
    p = plan_profile(np.array([[0, 0, 30], [200, 0, 30], [200, 200, 30]]), kin)
    t, pos = p.sample(0.03)
    att, vel = attitude_from_motion(t, pos, kin)
    deg = np.rad2deg(att)
    mid = np.searchsorted(t, p.t_vertex[1] / 2)
    assert deg[mid, 2] == pytest.approx(90.0, abs=1.0)          # flying east: yaw 90 (clockwise from north)
    assert deg[mid, 1] == pytest.approx(-3.0, abs=0.5)          # steady nose-down pitch against drag
    assert abs(deg[mid, 0]) < 0.5
    early = np.searchsorted(t, 1.0)
    assert deg[early, 1] < deg[mid, 1]                           # accelerating forward: more nose-down
    corner = np.searchsorted(t, p.t_vertex[1])
    assert deg[corner - 20:corner + 20, 0].min() < -3.0          # left turn (east -> north): left wing down
    end = np.searchsorted(t, p.t_vertex[2] - 3)
    assert deg[end, 2] == pytest.approx(0.0, abs=1.0) or deg[end, 2] == pytest.approx(360.0, abs=1.0)
    assert np.abs(deg[:, :2]).max() <= kin.max_tilt_deg


def test_fixed_heading_holds_the_nose_and_tilts_along_the_motion():
    """A fixed-heading vehicle (as AERPAW's AFAR flights) never turns its nose; flying east with the nose north
    it rolls right (not pitches) against drag, and the tilt magnitude equals the course-following case."""
    path = np.array([[0, 0, 30], [200, 0, 30], [200, 200, 30]])
    free = Kinematics(cruise_speed_mps=5.0)
    fixed = Kinematics(cruise_speed_mps=5.0, heading_deg=0.0)
    p = plan_profile(path, fixed)
    t, pos = p.sample(0.03)
    att_f, _ = attitude_from_motion(t, pos, fixed)
    att_c, _ = attitude_from_motion(t, pos, free)
    assert np.all(att_f[:, 2] == 0.0)
    mid = np.searchsorted(t, p.t_vertex[1] / 2)
    deg = np.rad2deg(att_f[mid])
    assert deg[0] == pytest.approx(3.0, abs=0.5)    # flying east, nose north: right wing down against drag
    assert abs(deg[1]) < 0.5                         # no pitch: no motion along the nose
    tilt_f = np.hypot(att_f[:, 0], att_f[:, 1])
    tilt_c = np.hypot(att_c[:, 0], att_c[:, 1])
    assert np.allclose(tilt_f[mid], tilt_c[mid], atol=np.deg2rad(0.05))
    east = Kinematics(cruise_speed_mps=5.0, heading_deg=90.0)
    att_e, _ = attitude_from_motion(t, pos, east)
    assert np.rad2deg(att_e[mid, 1]) == pytest.approx(np.rad2deg(att_c[mid, 1]), abs=0.05)  # nose east = course
