"""Near-nadir loss: a body-fixed loss over a band of depression angles below the UAV, and what the data can show.

Why: the airframe, battery and payload sit below the UAV's antenna, so rays leaving the body at steep
depression angles can lose several dB whatever their azimuth.  The free-form body map (``rx_gain_map``) can
draw it only where its Legendre basis and smoothness penalty allow, and the flights see those angles only
when the UAV is almost above the rover (at 30 m, depression > 60 deg means < 17 m horizontally).  So:

- ``near_nadir``: a named candidate, elevation only: ``-depth_db exp(-(dep_b - centre)^2 / 2 width^2)``
  (depth, centre and width fitted from a grid of starts);
- ``power_statement``: how many samples the flights have in the band, their effective number (block
  length from the residual's autocorrelation), the smallest loss they could detect (one-sided 5 %, power
  80 %), and how many samples a flight would need to detect a given loss.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from mission.gap.candidate import Candidate, Param
from mission.gap.pipeline import Pipeline

BAND_DEG = (60.0, 90.0)
Z_ALPHA, Z_POWER = 1.645, 0.842  # one-sided 5 %, power 80 %


@dataclass(frozen=True)
class NearNadirLoss:
    """Loss ``depth_db`` centred on body depression ``centre_deg`` (gaussian of ``width_deg``), any azimuth."""

    depth_db: float = 0.0
    centre_deg: float = 75.0
    width_deg: float = 10.0
    name: ClassVar[str] = "near_nadir"

    def rss_term_db(self, link: Any) -> np.ndarray:
        ubz = link.u_b[2]
        dep = np.degrees(np.arcsin(np.clip(ubz / link.d_los, -1.0, 1.0)))
        term = -self.depth_db * np.exp(-0.5 * ((dep - self.centre_deg) / max(self.width_deg, 0.5)) ** 2)
        return term.astype(np.asarray(link.d_los).dtype, copy=False)


def near_nadir_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        e = NearNadirLoss(float(th["depth_db"]), float(th["centre_deg"]), float(th["width_deg"]))
        return p.replace(model=p.model.with_effect(e))

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without("near_nadir")) if p.model.has("near_nadir") else p

    return Candidate("near_nadir", "body-fixed loss over a band of depression angles below the UAV", (
        Param("depth_db", -5.0, 25.0, (3.0, 8.0), unit="dB"),
        Param("centre_deg", 20.0, 90.0, (35.0, 50.0, 65.0, 80.0), unit="deg"),
        Param("width_deg", 2.0, 30.0, (4.0, 10.0), unit="deg")),
        build, lambda p: p.model.has("attitude") and not p.model.has("near_nadir"), withhold)


def power_statement(dep_deg: Sequence[np.ndarray], resid: Sequence[np.ndarray], block_lens: Sequence[int],
                    band: tuple[float, float] = BAND_DEG, loss_db: float = 3.0) -> dict[str, Any]:
    """What the flights can show about a loss in ``band`` of body depression (module docstring).

    A loss D in the band shifts the band's mean residual by D against the rest; with residual sd s and
    n_eff effectively independent samples in the band (n / block length), the smallest detectable D is
    (z_alpha + z_power) s / sqrt(n_eff), and detecting ``loss_db`` needs n_eff = ((z_a + z_p) s / D)^2.
    A held-out test also needs the band in at least two separate passes (one to fit, one to score: the
    folds are contiguous chunks); with fewer, nothing is detectable whatever the count.
    """
    n, n_eff, ss, passes = 0, 0.0, [], 0
    for dep, r, L in zip(dep_deg, resid, block_lens, strict=True):
        ok = np.isfinite(r)
        inb = ok & (dep >= band[0]) & (dep <= band[1])
        n += int(inb.sum())
        n_eff += float(inb.sum()) / max(int(L), 1)
        idx = np.nonzero(inb)[0]
        passes += int(idx.size > 0) + int(np.sum(np.diff(idx) > max(int(L), 10)))
        if ok.any():
            ss.append(r[ok] - np.median(r[ok]))
    s = float(np.std(np.concatenate(ss))) if ss else float("nan")
    z = Z_ALPHA + Z_POWER
    detectable = z * s / math.sqrt(n_eff) if n_eff > 0 and passes >= 2 else float("inf")
    need_eff = (z * s / loss_db) ** 2
    L_mean = n / n_eff if n_eff > 0 else float(np.mean(block_lens)) if len(block_lens) else 1.0
    need = int(math.ceil(need_eff * L_mean))
    seen = (f"a loss there smaller than {detectable:.1f} dB cannot be seen" if passes >= 2 else
            f"in {passes} pass{'es' if passes != 1 else ''}, so a held-out test cannot see a loss there at all")
    text = (f"Below the UAV ({band[0]:.0f}-{band[1]:.0f} deg depression) the flights have {n} samples "
            f"({n_eff:.0f} independent): {seen}; {loss_db:.0f} dB would need about {need} samples "
            f"({need_eff:.0f} independent) in at least two passes.")
    return {"band_deg": list(band), "samples": n, "passes": passes, "effective_samples": n_eff, "residual_sd_db": s,
            "detectable_db": detectable, "loss_db": loss_db, "samples_needed": need,
            "effective_needed": need_eff, "alpha": 0.05, "power": 0.8, "statement": text}
