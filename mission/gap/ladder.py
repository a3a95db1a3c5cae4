"""The greedy ladder of the gap diagnosis: base -> + best candidate -> + next, while the best is
significant.

Why its own module: a rung whose best is a ground map (or a body-angle map that a ground map
out-explains) asks ``frame`` whether the effect is ground- or body-fixed, and ``frame`` refits
candidates with ``fit``; the ladder sits above both, so neither imports the other back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mission.gap.candidate import FRAME_BODY, FRAME_GROUND, TIER_SMOOTHER, Candidate
from mission.gap.describe import describe_params
from mission.gap.fit import (
    CandidateResult,
    FitConfig,
    Progress,
    heldout_residuals,
    make_folds,
    rank_candidates,
)
from mission.gap.frame import frame_for
from mission.gap.pipeline import Pipeline
from mission.samples import FlightSamples


@dataclass
class Rung:
    """One rung of the ladder: the pipelines (per fold), their held-out residuals and what was
    added."""

    label: str
    added: str | None
    pipes: list[Pipeline]
    residuals: list[np.ndarray]
    params: dict[str, Any] = field(default_factory=dict)
    # candidates tried on top of this rung
    ranking: list[CandidateResult] = field(default_factory=list)
    frame: dict[str, Any] | None = (
        None  # ground- or body-fixed test of this rung's ranking (``frame.frame_for``)
    )

    def describe(self) -> dict[str, Any]:
        return describe_params(self.pipes[0])


def ladder(
    base: Pipeline,
    flights: Sequence[FlightSamples],
    candidates: Sequence[Candidate],
    cfg: FitConfig,
    max_rungs: int = 6,
    label: str = "base",
    progress: Progress | None = None,
) -> list[Rung]:
    """Greedy ladder: base -> +best -> +next ... while the best remaining candidate is
    significant."""
    rng = np.random.default_rng(cfg.seed)
    folds = make_folds(flights, cfg)
    pipes = [base] * len(folds)
    rung = Rung(label, None, pipes, heldout_residuals(pipes, flights, folds, cfg))
    rungs = [rung]
    pool = list(candidates)
    costs: dict[str, float] = {}  # seconds per fit, from the last ranking: the costliest go first
    while pool and len(rungs) <= max_rungs:
        ranking = rank_candidates(
            rung.pipes,
            flights,
            folds,
            pool,
            cfg,
            rng,
            rung.residuals,
            progress,
            f"rung {len(rungs)}",
            costs,
        )
        rung.ranking = ranking
        sig = [r for r in ranking if r.significant]
        physical = [r for r in sig if r.tier != TIER_SMOOTHER]
        if not sig:
            break
        best = physical[0] if physical else sig[0]
        if best.name in FRAME_GROUND or (
            best.name in FRAME_BODY
            and any(
                r.name in FRAME_GROUND and r.loss_reduction >= best.loss_reduction for r in ranking
            )
        ):
            # a ground map would absorb it, or explains more than the body-angle map chosen: add the
            # one that holds out across headings and on unseen ground (``frame``)
            rung.frame = frame_for(ranking, rung.pipes[0], flights, cfg, cfg.seed)
            if (
                rung.frame is not None
                and rung.frame["winner"] is not None
                and best.name != rung.frame["winner"]
            ):
                loser = (
                    rung.frame["ground"]
                    if rung.frame["winner"] == rung.frame["body"]
                    else rung.frame["body"]
                )
                sig = [r for r in sig if r.name != loser]
                physical = [r for r in sig if r.tier != TIER_SMOOTHER]
                if not sig:
                    break
                best = physical[0] if physical else sig[0]
        rung = Rung(
            f"{rung.label} + {best.name}", best.name, best.pipes, best.residuals, best.params_mean()
        )
        rungs.append(rung)
        pool = [c for c in pool if c.name != best.name]
    return rungs
