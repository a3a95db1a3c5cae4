"""Multicopter kinematics: limits respected, closed-form leg times, attitude signs and
magnitudes."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from mission.importers.afar import AFAR2023_TRUTH, convert_afar_mat
from mission.spec import load_mission
from mission.trajectory.attitude import AttitudeState, ou_process, run_attitude
from mission.trajectory.kinematics import (
    Kinematics,
    attitude_from_motion,
    initial_course,
    plan_profile,
)


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
    wp = np.array(
        [[0, 0, 0], [0, 0, 30], [120, 0, 30], [120, 80, 30], [-40, 80, 30], [0, 0, 30], [0, 0, 0]]
    )
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
    assert 0 < p.v_vertex[1] < 5.0  # 90 deg corner: cos(45)^2 * 5 = 2.5 m/s
    assert p.v_vertex[1] == pytest.approx(2.5)
    assert p.v_vertex[2] == pytest.approx(0.0, abs=1e-9)  # 180 deg reversal


def test_attitude_follows_motion():
    kin = Kinematics(cruise_speed_mps=5.0)
    p = plan_profile(np.array([[0, 0, 30], [200, 0, 30], [200, 200, 30]]), kin)
    t, pos = p.sample(0.03)
    att, vel = attitude_from_motion(t, pos, kin)
    deg = np.rad2deg(att)
    mid = np.searchsorted(t, p.t_vertex[1] / 2)
    assert deg[mid, 2] == pytest.approx(90.0, abs=1.0)  # flying east: yaw 90 (clockwise from north)
    assert deg[mid, 1] == pytest.approx(-3.0, abs=0.5)  # steady nose-down pitch against drag
    assert abs(deg[mid, 0]) < 0.5
    early = np.searchsorted(t, 1.0)
    assert deg[early, 1] < deg[mid, 1]  # accelerating forward: more nose-down
    corner = np.searchsorted(t, p.t_vertex[1])
    # left turn (east -> north): left wing down
    assert deg[corner - 20 : corner + 20, 0].min() < -3.0
    end = np.searchsorted(t, p.t_vertex[2] - 3)
    assert deg[end, 2] == pytest.approx(0.0, abs=1.0) or deg[end, 2] == pytest.approx(
        360.0, abs=1.0
    )
    assert np.abs(deg[:, :2]).max() <= kin.max_tilt_deg


def test_fixed_heading_holds_the_nose_and_tilts_along_the_motion():
    """A fixed-heading vehicle (as AERPAW's AFAR flights) never turns its nose; flying east with the
    nose north it rolls right (not pitches) against drag, and the tilt magnitude equals the
    course-following case."""
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
    # flying east, nose north: right wing down against drag
    assert deg[0] == pytest.approx(3.0, abs=0.5)
    assert abs(deg[1]) < 0.5  # no pitch: no motion along the nose
    tilt_f = np.hypot(att_f[:, 0], att_f[:, 1])
    tilt_c = np.hypot(att_c[:, 0], att_c[:, 1])
    assert np.allclose(tilt_f[mid], tilt_c[mid], atol=np.deg2rad(0.05))
    east = Kinematics(cruise_speed_mps=5.0, heading_deg=90.0)
    att_e, _ = attitude_from_motion(t, pos, east)
    # nose east = course
    assert np.rad2deg(att_e[mid, 1]) == pytest.approx(np.rad2deg(att_c[mid, 1]), abs=0.05)


def test_attitude_model_stepped_equals_vectorised():
    """The vehicle runs the attitude model in chunks of any size (one sample: a step); the result
    must be the whole-array result of the fast simulator, wind and turbulence included."""
    kin = Kinematics(cruise_speed_mps=6.0)
    p = plan_profile(
        np.array([[0, 0, 0], [0, 0, 30], [150, 0, 30], [150, 120, 30], [20, 40, 30]]), kin
    )
    dt = 0.02
    t, pos = p.sample(dt)
    rng = np.random.default_rng(3)
    g = rng.standard_normal((len(t), 4))
    wind = ou_process(g[:, :2], dt, 6.0, 1.5, np.zeros(2))
    turb = ou_process(g[:, 2:], dt, 0.6, np.deg2rad(0.8), np.zeros(2))
    s0 = AttitudeState.at_rest(pos[0], 0.3)
    whole, vel_w, end_w = run_attitude(pos, dt, kin, s0, wind, turb)
    parts, state, i = [], s0, 0
    sizes = np.concatenate([np.ones(200, int), rng.integers(1, 400, size=len(t))])
    for k in sizes:
        if i >= len(t):
            break
        att, _, state = run_attitude(
            pos[i : i + k], dt, kin, state, wind[i : i + k], turb[i : i + k]
        )
        parts.append(att)
        i += k
    stepped = np.concatenate(parts)
    np.testing.assert_allclose(stepped[:, :2], whole[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(stepped[:, 2] - whole[:, 2]), 1.0, atol=1e-12)
    assert state.yaw == pytest.approx(end_w.yaw) and np.allclose(state.vel, end_w.vel)
    # the chunked OU process is the whole one too
    x = ou_process(g[:100, :2], dt, 6.0, 1.5, np.zeros(2))
    y = ou_process(g[100:200, :2], dt, 6.0, 1.5, x[-1])
    np.testing.assert_allclose(np.concatenate([x, y]), wind[:200], atol=1e-12)


def test_attitude_is_causal():
    """Changing the path after time T leaves the attitude before T untouched (the vehicle cannot
    look ahead)."""
    kin = Kinematics()
    p1 = plan_profile(np.array([[0, 0, 30], [100, 0, 30], [100, 100, 30]]), kin)
    p2 = plan_profile(np.array([[0, 0, 30], [100, 0, 30], [100, -100, 30]]), kin)
    t, a = p1.sample(0.03)
    _, b = p2.sample(0.03)
    att1, _ = attitude_from_motion(t, a, kin)
    att2, _ = attitude_from_motion(t, b, kin)
    first_diff = int(np.argmax(np.any(np.abs(a - b) > 1e-9, axis=1)))
    assert first_diff > 100
    np.testing.assert_array_equal(att1[:first_diff], att2[:first_diff])
    # opposite turns
    assert np.abs(att1[first_diff + 50 :, 0] - att2[first_diff + 50 :, 0]).max() > np.deg2rad(3)


# Real AFAR 2023 cruise attitude (six flights, samples above 80 % of the 95th-percentile height),
# degrees: `.venv/bin/python -m pytest tests/test_kinematics.py -k real_afar` recomputes these when
# ../shared is there.
AFAR_ROLL_P5_P95 = (-5.7, 5.5)
AFAR_PITCH_P5_P50_P95 = (-7.5, -2.2, 2.7)


def _spiral_attitude(heading_deg=None, seed=0):
    """The spiral mission flown by the attitude model with the simulated vehicle's gusts and
    turbulence."""
    spec = load_mission(Path(__file__).resolve().parents[1] / "missions" / "spiral.yaml")
    kin = dataclasses.replace(spec.kinematics(), heading_deg=heading_deg)
    dt = 0.03
    t, pos = plan_profile(spec.flight_path_enu(), kin).sample(dt)
    g = np.random.default_rng(seed).standard_normal((len(t), 4))
    # sitl.protocol: WIND_TAU_S, --gust default
    wind = ou_process(g[:, :2], dt, 6.0, 1.5, np.zeros(2))
    turb = ou_process(g[:, 2:], dt, 0.6, math.radians(0.8), np.zeros(2))  # TURB_TAU_S, TURB_DEG
    att, _, _ = run_attitude(
        pos, dt, kin, AttitudeState.at_rest(pos[0], initial_course(pos)), wind, turb
    )
    cruise = pos[:, 2] > 0.8 * 30.0
    return np.rad2deg(att[cruise])


def test_simulated_cruise_attitude_is_near_real_afar():
    """Course-following spiral: pitch percentiles (steady nose-down against drag) within 1.5 deg of
    the real flights; fixed-heading spiral (as the AFAR vehicles flew, nose north): roll percentiles
    within 1.5 deg."""
    course = _spiral_attitude()
    pitch = np.percentile(course[:, 1], [5, 50, 95])
    assert np.all(np.abs(pitch - AFAR_PITCH_P5_P50_P95) < 1.5), pitch
    fixed = _spiral_attitude(heading_deg=345.0)
    roll = np.percentile(fixed[:, 0], [5, 95])
    assert np.all(np.abs(roll - AFAR_ROLL_P5_P95) < 1.5), roll
    # hard corners stay below ArduPilot's 30 deg lean limit
    assert np.abs(course[:, :2]).max() < 25.0


@pytest.mark.real
def test_real_afar_cruise_attitude_constants():
    """The real-flight figures above, recomputed from the AFAR MAT files (skips where ../shared is
    absent)."""
    mat = Path(__file__).resolve().parents[2] / "shared" / "data" / "afar2023" / "mat"
    if not mat.exists():
        pytest.skip("AFAR data not in ../shared/data/afar2023/mat")

    roll, pitch = [], []
    for team in (288, 328):
        for loc in (1, 2, 3):
            c = convert_afar_mat(
                mat / f"results_useful_ori_exp_{team}_loc_{loc}.mat", AFAR2023_TRUTH[loc]
            ).log.columns
            cruise = c["rel_alt_m"] > 0.8 * np.percentile(c["rel_alt_m"], 95)
            roll.append(c["roll_deg"][cruise])
            pitch.append(c["pitch_deg"][cruise])
    np.testing.assert_allclose(
        np.percentile(np.concatenate(roll), [5, 95]), AFAR_ROLL_P5_P95, atol=0.1
    )
    np.testing.assert_allclose(
        np.percentile(np.concatenate(pitch), [5, 50, 95]), AFAR_PITCH_P5_P50_P95, atol=0.1
    )
