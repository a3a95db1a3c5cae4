"""The mission's ``adaptive:`` block: how long to survey, the pattern flown around the live
estimate, when to stop.

Why a block of its own: the same mission file flies fixed (the whole trajectory) or adaptive (the
trajectory's first ``survey_s`` seconds, then rounds planned in flight); ``fly-mission --adaptive``
or ``enabled: true`` choose.  Bad settings are refused before take-off
(``mission.adaptive.feasibility``): an altitude outside the limits, a pattern that fits nowhere
inside the fence, a budget that cannot hold the survey, one round and the return.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class AdaptiveSpec:
    """Settings of the adaptive finish (schema in missions/spiral_adaptive.yaml)."""

    enabled: bool = False
    survey_s: float = (
        300.0  # seconds of the trajectory (from its first waypoint) flown before adapting
    )
    altitude_m: float | None = None  # altitude of the adaptive legs (None: the mission's)
    radius_m: float = 20.0  # half side of the square flown around the live estimate
    min_radius_m: float = 6.0  # a round is shrunk down to this to fit fence or budget, else refused
    target_area_m2: float = 150.0  # stop adapting once the 90 % region is this small
    lead_s: float = (
        30.0  # plan the next round this many vehicle seconds before the current one ends
    )
    update_s: float = 5.0  # live estimate period (vehicle seconds)
    reserve_s: float = 15.0  # kept free in the budget beyond the return and landing
    explore: bool = True  # fly over the posterior's competing peaks in turn (planner.choose_target)
    # choose each round where the top hypotheses predict the most different RSS
    # (planner.separating_target); overrides ``explore``
    separate: bool = False
    # fly first over the candidate the networks' physics explains best (the adaptive answer's
    # judge, ``methods.JUDGED_PICK``) until its square is flown; overrides both above. Adopted by
    # its rule (benchmarks/score_answer_first.py: 13 fresh SITL seeds -3.1 [-7.9, 0.5] m, the
    # fast simulator under the mission's physics -0.7 [-1.5, -0.1] m, the afar family unmoved)
    answer_first: bool = True

    def altitude(self, spec) -> float:
        return float(spec.altitude_m if self.altitude_m is None else self.altitude_m)


def parse_adaptive(r) -> AdaptiveSpec:
    """The ``adaptive:`` mapping (a ``mission.fields.Fields``) -> ``AdaptiveSpec``; errors name
    ``adaptive.<key>``."""
    d = AdaptiveSpec()  # every default is the dataclass's
    en = r.bool_("enabled", d.enabled)
    ex = r.bool_("explore", d.explore)
    sep = r.bool_("separate", d.separate)
    first = r.bool_("answer_first", d.answer_first)
    alt = (
        r.num("altitude_m", math.nan, 0.0, strict_lo=True) if r.has("altitude_m") else d.altitude_m
    )
    r.used.add("altitude_m")
    radius = r.num("radius_m", d.radius_m, 0.0, strict_lo=True)
    out = AdaptiveSpec(
        enabled=en,
        survey_s=r.num("survey_s", d.survey_s, 0.0, strict_lo=True),
        altitude_m=alt,
        radius_m=radius,
        min_radius_m=r.num(
            "min_radius_m", min(d.min_radius_m, radius), 0.0, radius, strict_lo=True
        ),
        target_area_m2=r.num("target_area_m2", d.target_area_m2, 0.0),
        lead_s=r.num("lead_s", d.lead_s, 0.0),
        update_s=r.num("update_s", d.update_s, 0.5),
        reserve_s=r.num("reserve_s", d.reserve_s, 0.0),
        explore=ex,
        separate=sep,
        answer_first=first,
    )
    r.done()
    return out
