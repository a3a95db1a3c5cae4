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
from mission.trajectory.kinematics import plan_profile


def adaptive_violations(
    spec, a: AdaptiveSpec, return_extra_s: float = 0.0
) -> list[tuple[str, str]]:
    """(key, one-line message) for settings that cannot be flown: altitude, fence fit, budget; with
    ``return_extra_s``, the seconds the autopilot's own return and landing take beyond the kinematic
    plan (known once connected: ``rounds.autopilot_return_extra_s``; ArduCopter SITL 26 s)."""
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
    path = np.vstack(
        [
            home,
            [home[0], home[1], survey.vertices[0, 2]],
            survey.vertices,
            first,
            [home[0], home[1], alt],
            home,
        ]
    )
    need = plan_profile(path, spec.kinematics()).duration_s + a.reserve_s + return_extra_s
    if need > spec.time_budget_s:
        own = (
            f", the autopilot's return {return_extra_s:.0f} s longer"
            if return_extra_s > 0.5
            else ""
        )
        out.append(
            (
                "time_budget_s",
                f"time budget {spec.time_budget_s:g} s is too small for the survey "
                f"({a.survey_s:g} s), one adaptive round and the return with "
                f"{a.reserve_s:g} s reserve{own} ({need:.0f} s needed)",
            )
        )
    return out


def assert_adaptive(spec, a: AdaptiveSpec, return_extra_s: float = 0.0) -> None:
    """Refuse unflyable adaptive settings with one ``InputError`` naming the mission file and
    key."""
    v = adaptive_violations(spec, a, return_extra_s)
    if v:
        more = f" (and {len(v) - 1} more problems)" if len(v) > 1 else ""
        raise InputError(v[0][1] + more, source=spec.source_name, field=v[0][0])
