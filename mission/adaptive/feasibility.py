"""Whether a mission's adaptive settings can be flown: altitude limits, a pattern inside the fence,
the budget.

Why apart from ``config``: the mission parser reads the ``adaptive:`` block (``config``) while these
checks plan flights (``planner``, which reads the mission spec); kept here, no import runs in a
circle.
"""

from __future__ import annotations

import numpy as np

from mission.adaptive.config import AdaptiveSpec
from mission.adaptive.planner import box_pattern, fit_centre, survey_profile
from mission.errors import InputError
from mission.trajectory.autopilot import ReturnModel
from mission.trajectory.kinematics import plan_profile


def adaptive_violations(
    spec, a: AdaptiveSpec, returns: ReturnModel | None = None
) -> list[tuple[str, str]]:
    """(key, one-line message) for settings that cannot be flown: altitude, fence fit, budget; with
    ``returns``, the autopilot's own return and landing (known once connected: the budget plan's
    ``returns``; ArduCopter SITL's took 26 s more than the kinematic plan's, PX4's climbs from a
    15 m round to 30 m first), else the mission's kinematics."""
    own = ReturnModel.of(spec)
    returns = returns or own
    out: list[tuple[str, str]] = []
    lo, hi = spec.altitude_limits_m
    alt = a.altitude(spec)
    if not lo <= alt <= hi:
        out.append(
            (
                "adaptive.altitude_m",
                f"adaptive altitude {alt:g} m is outside the altitude limits [{lo:g}, {hi:g}] m",
            )
        )
    ra = spec.field.rover_area
    c = fit_centre(spec, np.asarray(ra.vertices, dtype=float).mean(axis=0), a.min_radius_m)
    if c is None:
        out.append(
            (
                "adaptive.radius_m",
                f"the adaptive pattern (a {2 * a.min_radius_m:g} m square at "
                f"least) fits nowhere in the flight area with the {spec.fence_margin_m:g}"
                " m fence margin",
            )
        )
        return out
    survey = survey_profile(spec, a.survey_s)
    home = np.asarray(spec.home_enu, dtype=float)
    first = box_pattern(c, a.min_radius_m, alt)
    path = np.vstack([home, [home[0], home[1], survey.vertices[0, 2]], survey.vertices, first])
    back = returns.seconds(first[-1])
    need = plan_profile(path, spec.kinematics()).duration_s + back + a.reserve_s
    if need > spec.time_budget_s:
        longer = back - own.seconds(first[-1])
        said = f", the autopilot's return {longer:.0f} s longer" if longer > 0.5 else ""
        out.append(
            (
                "time_budget_s",
                f"time budget {spec.time_budget_s:g} s is too small for the survey "
                f"({a.survey_s:g} s), one adaptive round and the return with "
                f"{a.reserve_s:g} s reserve{said} ({need:.0f} s needed)",
            )
        )
    return out


def assert_adaptive(spec, a: AdaptiveSpec) -> None:
    """Refuse unflyable adaptive settings with one ``InputError`` naming the mission file and
    key."""
    v = adaptive_violations(spec, a)
    if v:
        more = f" (and {len(v) - 1} more problems)" if len(v) > 1 else ""
        raise InputError(v[0][1] + more, source=spec.source_name, field=v[0][0])
