"""One candidate effect of the gap diagnosis: its parameters, how to build, fit and withhold it.

Why a module of its own: the effect library (``candidates``), the free-form shapes (``freeform``)
and the spatial smoother (``spatial``) all define candidates; the fitting code (``fit``) only needs
this interface.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from mission.gap.pipeline import Pipeline

# ranking tiers (``mission.gap.fit.rank_key``): named physical effects explain, free-form shapes
# describe, smoothers interpolate
TIER_NAMED, TIER_FREEFORM, TIER_SMOOTHER = "named", "free-form", "smoother"
# candidates fixed to the UAV's body (its angles) and to the ground: when one of each explains a
# residual, ``mission.gap.frame`` tests which holds out across headings
FRAME_BODY = (
    "leg_shadowing",
    "rx_gain_map",
    "near_nadir",
    "rx_pattern",
    "rx_mounting",
    "attitude",
    "yaw_attitude",
)
FRAME_GROUND = ("spatial_shadowing", "site_map")


@dataclass(frozen=True)
class Param:
    """A continuous parameter: bounds, a coarse start grid and (for angles) a period."""

    name: str
    lo: float
    hi: float
    grid: tuple[float, ...]
    period: float | None = None
    unit: str = ""


Builder = Callable[[Pipeline, dict[str, float], dict[str, Any]], Pipeline]


@dataclass(frozen=True)
class Candidate:
    """One candidate effect (see the module table)."""

    name: str
    description: str
    params: tuple[Param, ...]
    build: Builder
    applicable: Callable[[Pipeline], bool]
    withhold: Callable[[Pipeline], Pipeline]
    choices: Callable[[Pipeline], Sequence[dict[str, Any]]] = field(default=lambda p: ({},))
    post_only: bool = (
        False  # only changes the post-processing (the channel prediction can be cached)
    )
    direct_fit: Callable[..., tuple[Pipeline, dict[str, Any]]] | None = (
        None  # (pipe, flights, idx, resid, rng, cfg)
    )
    params_of: Callable[[Pipeline], tuple[Param, ...]] | None = (
        None  # parameters that depend on the pipeline
    )
    tier: str = TIER_NAMED

    def params_for(self, p: Pipeline) -> tuple[Param, ...]:
        """The parameters fitted on top of ``p`` (``params`` unless they depend on the pipeline)."""
        return self.params if self.params_of is None else self.params_of(p)
