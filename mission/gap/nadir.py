"""Near-nadir loss: a body-fixed loss over a band of depression angles below the UAV, and what the
data can show.

Why: the airframe, battery and payload sit below the UAV's antenna, so rays leaving the body at
steep depression angles can lose several dB whatever their azimuth.  The free-form body map
(``rx_gain_map``) can draw it only where its Legendre basis and smoothness penalty allow, and the
flights see those angles only when the UAV is almost above the rover (at 30 m, depression > 60 deg
means < 17 m horizontally).  So:

- ``near_nadir``: a named candidate, elevation only: ``-depth_db exp(-(dep_b - centre)^2 / 2
  width^2)`` (depth, centre and width fitted from a grid of starts);
- what the flights can show in the band (the smallest loss a held-out test on them would find, and
  the samples a flight would need): ``mission.gap.power.power_statement``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from mission.gap.candidate import Candidate, Param
from mission.gap.pipeline import Pipeline
from mission.physics.geometry import depression

BAND_DEG = (60.0, 90.0)
Z_ALPHA, Z_POWER = 1.645, 0.842  # one-sided 5 %, power 80 %


@dataclass(frozen=True)
class NearNadirLoss:
    """Loss ``depth_db`` centred on body depression ``centre_deg`` (gaussian of ``width_deg``), any
    azimuth."""

    depth_db: float = 0.0
    centre_deg: float = 75.0
    width_deg: float = 10.0
    name: ClassVar[str] = "near_nadir"

    def rss_term_db(self, link: Any) -> np.ndarray:
        dep = np.degrees(depression(link.u_b[2], link.d_los))
        term = -self.depth_db * np.exp(
            -0.5 * ((dep - self.centre_deg) / max(self.width_deg, 0.5)) ** 2
        )
        return term.astype(np.asarray(link.d_los).dtype, copy=False)


def near_nadir_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        e = NearNadirLoss(float(th["depth_db"]), float(th["centre_deg"]), float(th["width_deg"]))
        return p.replace(model=p.model.with_effect(e))

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without("near_nadir")) if p.model.has("near_nadir") else p

    return Candidate(
        "near_nadir",
        "body-fixed loss over a band of depression angles below the UAV",
        (
            Param("depth_db", -5.0, 25.0, (3.0, 8.0), unit="dB"),
            Param("centre_deg", 20.0, 90.0, (35.0, 50.0, 65.0, 80.0), unit="deg"),
            Param("width_deg", 2.0, 30.0, (4.0, 10.0), unit="deg"),
        ),
        build,
        lambda p: p.model.has("attitude") and not p.model.has("near_nadir"),
        withhold,
    )
