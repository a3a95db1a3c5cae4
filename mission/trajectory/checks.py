"""Pre-flight checks: geofence, altitude limits and time budget, before anything is uploaded or
flown.

The flight time is estimated with ``plan_profile`` on ``MissionSpec.flight_path_enu`` (take-off,
transit, the trajectory, return and landing), the same kinematics the simulator and the simulated
vehicle fly, so a mission that passes here also fits its budget in simulation.

Fence rule: every trajectory waypoint and every leg between them must be inside the flight area with
at least ``fence_margin_m`` to its edge.  The take-off point is wherever the crew launches (AERPAW's
launch point is 0.4 m inside the AFAR fence), so the climb, the transit legs to/from home and the
landing need only stay inside the flight area; home itself must keep ``RETURN_OVERSHOOT_M`` (the
largest return and landing overshoot measured on an autopilot) plus the mission's ``home_margin_m``
from the edge.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mission.errors import InputError
from mission.trajectory.kinematics import FlightProfile, plan_profile

# metres a real autopilot's take-off, return and landing drift past home: PX4 v1.16 SITL's take-off
# and landing rows 0.9 m, ArduCopter 4.7 SITL's return 0.03 m (the AFAR launch point is only 0.44 m
# inside the fence)
RETURN_OVERSHOOT_M = 1.0
# metres: rounding in the geodetic round trip must not fail a waypoint placed on the margin
_TOL = 1e-6


@dataclass
class Violation:
    """One failed check: the mission key it concerns, a one-line message and the shortfall."""

    key: str
    message: str
    amount: float


@dataclass
class MissionReport:
    """Result of ``check_mission``: estimated length, time and clearances, and the violations
    found."""

    length_m: float
    duration_s: float
    time_budget_s: float
    n_waypoints: int
    n_samples: int  # RSS samples at the source's sample period over the whole flight
    min_fence_clearance_m: float  # smallest distance of a trajectory point to the flight-area edge
    altitude_range_m: tuple[float, float]
    profile: FlightProfile
    violations: list[Violation] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.violations

    @property
    def budget_used(self) -> float:
        """Fraction of the time budget the flight uses."""
        return self.duration_s / self.time_budget_s


def _wp_key(spec, i: int) -> str:
    return (
        f"trajectory.waypoints[{i}]"
        if spec.trajectory.waypoints is not None
        else "trajectory.params"
    )


def _leg_clearance(
    area, a: np.ndarray, b: np.ndarray, step: float = 0.5
) -> tuple[float, np.ndarray]:
    """Smallest signed clearance (m, negative outside) along the leg a -> b, and where it occurs."""
    n = max(int(np.ceil(np.linalg.norm(b[:2] - a[:2]) / step)), 1) + 1
    pts = a[:2] + np.linspace(0.0, 1.0, n)[:, None] * (b[:2] - a[:2])
    d = area.signed_distance(pts)
    j = int(np.argmin(d))
    return float(d[j]), pts[j]


def _where(d: float, margin: float) -> str:
    if d < 0:
        return f"{-d:.1f} m outside the flight area"
    return (
        f"only {d:.1f} m inside the flight area, {margin:g} m margin required "
        f"({margin - d:.1f} m short)"
    )


def source_violations(spec, tx=None) -> list[Violation]:
    """A fixed simulated transmitter (``tx`` or the mission's) must lie in the field (flight or
    rover area) and not below ground: one at (5000, 5000) m makes a flight whose localization cannot
    succeed."""
    tx = spec.source.tx if tx is None else tx
    if isinstance(tx, str):
        return []
    tx = np.asarray(tx, dtype=float)
    out = []
    fa, ra = spec.field.flight_area, spec.field.rover_area
    d = max(float(fa.signed_distance(tx[:2])), float(ra.signed_distance(tx[:2])))
    if d < -_TOL:
        out.append(
            Violation(
                "source.tx",
                f"transmitter at ({tx[0]:.1f}, {tx[1]:.1f}) m is {-d:.1f} m outside the "
                "flight and rover areas",
                -d,
            )
        )
    if tx[2] < 0:
        out.append(
            Violation("source.tx", f"transmitter height {tx[2]:g} m is below ground", -float(tx[2]))
        )
    return out


def check_mission(spec) -> MissionReport:
    """Check a ``MissionSpec``: fence (waypoints and legs), altitude limits and the time budget."""
    wps = spec.waypoints_enu()
    path = spec.flight_path_enu()
    profile = plan_profile(path, spec.kinematics())
    v, min_clear = fence_violations(spec, wps)
    v += home_violations(spec, wps)
    v += altitude_violations(spec, wps)
    v += source_violations(spec)
    v += budget_violations(spec, profile)
    n_samples = int(np.floor(profile.duration_s / spec.source.sample_period_s + 1e-9)) + 1
    return MissionReport(
        profile.length_m,
        profile.duration_s,
        spec.time_budget_s,
        len(wps),
        n_samples,
        min_clear,
        (float(wps[:, 2].min()), float(wps[:, 2].max())),
        profile,
        v,
    )


def fence_violations(spec, wps: np.ndarray) -> tuple[list[Violation], float]:
    """Waypoints and legs closer to the fence than the margin (a leg only when neither end is
    already named), and the smallest clearance."""
    area, margin = spec.field.flight_area, spec.fence_margin_m
    v: list[Violation] = []
    clear = area.signed_distance(wps[:, :2])
    for i in np.flatnonzero(clear < margin - _TOL):
        v.append(
            Violation(
                _wp_key(spec, i),
                f"waypoint {i} at ({wps[i, 0]:.1f}, {wps[i, 1]:.1f}) m is "
                f"{_where(float(clear[i]), margin)}",
                float(margin - clear[i]),
            )
        )
    min_clear = float(clear.min())
    bad_wp = set(np.flatnonzero(clear < margin - _TOL).tolist())
    for i in range(len(wps) - 1):
        d, at = _leg_clearance(area, wps[i], wps[i + 1])
        min_clear = min(min_clear, d)
        if d < margin - _TOL and not ({i, i + 1} & bad_wp):
            v.append(
                Violation(
                    _wp_key(spec, i),
                    f"leg from waypoint {i} to {i + 1} passes ({at[0]:.1f}, "
                    f"{at[1]:.1f}) m, {_where(d, margin)}",
                    margin - d,
                )
            )
    return v, min_clear


def home_violations(spec, wps: np.ndarray) -> list[Violation]:
    """Home too close to the fence for the return overshoot, and the transits from and back to
    home leaving the flight area."""
    area = spec.field.flight_area
    v: list[Violation] = []
    home = np.asarray(spec.home_enu, dtype=float)
    legs = [(home, wps[0], "transit from home to waypoint 0")]
    if spec.return_behaviour == "rtl":
        legs.append((wps[-1], home, f"return from waypoint {len(wps) - 1} to home"))
    need, h_clear = (
        RETURN_OVERSHOOT_M + spec.home_margin_m,
        float(area.signed_distance(home[None, :2])[0]),
    )
    if h_clear < need - _TOL:
        v.append(
            Violation(
                "home",
                f"home at ({home[0]:.1f}, {home[1]:.1f}) m is "
                + (
                    f"{-h_clear:.1f} m outside the flight area"
                    if h_clear < 0
                    else f"only {h_clear:.1f} m inside the flight area, {need:g} m required "
                    "(return "
                    f"overshoot {RETURN_OVERSHOOT_M:g} m + home_margin_m {spec.home_margin_m:g})"
                ),
                need - h_clear,
            )
        )
    for a, b, what in legs:
        d, at = _leg_clearance(area, a, b)
        if d < -_TOL:
            v.append(
                Violation(
                    "home",
                    f"{what} passes ({at[0]:.1f}, {at[1]:.1f}) m, {-d:.1f} m outside "
                    "the flight area",
                    -d,
                )
            )
    return v


def altitude_violations(spec, wps: np.ndarray) -> list[Violation]:
    """Waypoints below or above the altitude limits."""
    v: list[Violation] = []
    lo, hi = spec.altitude_limits_m
    for i, z in enumerate(wps[:, 2]):
        if z < lo - _TOL:
            v.append(
                Violation(
                    _wp_key(spec, i) if spec.trajectory.waypoints is not None else "altitude_m",
                    f"waypoint {i} altitude {z:.1f} m is {lo - z:.1f} m below the lower limit "
                    f"{lo:g} m",
                    lo - z,
                )
            )
        elif z > hi + _TOL:
            v.append(
                Violation(
                    _wp_key(spec, i) if spec.trajectory.waypoints is not None else "altitude_m",
                    f"waypoint {i} altitude {z:.1f} m is {z - hi:.1f} m above the upper limit "
                    f"{hi:g} m",
                    z - hi,
                )
            )
    return v


def budget_violations(spec, profile) -> list[Violation]:
    """The estimated flight time over the time budget."""
    v: list[Violation] = []
    if profile.duration_s > spec.time_budget_s:
        over = profile.duration_s - spec.time_budget_s
        v.append(
            Violation(
                "time_budget_s",
                f"estimated flight time {profile.duration_s:.0f} s exceeds the "
                f"time budget {spec.time_budget_s:g} s by {over:.0f} s",
                over,
            )
        )
    return v


def assert_flyable(spec) -> MissionReport:
    """``check_mission``; raise an ``InputError`` (file, key, waypoint, shortfall) on the first
    violation."""
    rep = check_mission(spec)
    if rep.violations:
        first = rep.violations[0]
        more = f" (and {len(rep.violations) - 1} more problems)" if len(rep.violations) > 1 else ""
        raise InputError(first.message + more, source=spec.source_name, field=first.key)
    return rep
