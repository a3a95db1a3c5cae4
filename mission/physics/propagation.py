"""Propagation models as lists of named, separately switchable effects (SPEC section 3, paper eqs.
1-9).

A :class:`PropagationModel` is a tuple of effects; each effect is a frozen dataclass whose fields
are its parameters, so a model can be rebuilt with one effect removed (``without``), replaced or
added (``with_effect``) or refitted (``with_params``). Built-in effects:

``free_space``         direct ray: P_r = P_t + G_t + G_r + 20 log10(lambda / (4 pi d_los)) (Friis)
``ground_reflection``  two-ray, eq. 1: coherent sum with the ground-reflected ray, Fresnel Gamma
``tx_antenna``         transmitter pattern (rover frame: level, forward = north, plus heading/flip)
``rx_antenna``         receiver pattern (UAV body frame, antenna along the body z axis, up = -z_b)
``attitude``           receiver angles in the body frame (eqs. 3-6; SPEC section 1 transform)
``leg_shadowing``      eqs. 8-9: minus Upsilon = 10 beta log10(d_los / d_0) when S = 1
``path_gain_slope``    (optional, not in the named models) -10 n_extra log10(d_los / d_ref_m): a
                       path-gain exponent 2 + n_extra instead of Friis' 2 (fitted on the real AFAR
                       flights, see ``mission.physics.presets``)

Without ``attitude`` the body frame is level with yaw 0 (plain two-ray); with zero attitude the
enhanced two-ray model equals two-ray (+ shadowing) exactly. Any other effect that defines
``rss_term_db(link: Link) -> array`` (dB added to the RSS) is applied as well, so new effects plug
in.

Where things live: the effects in ``mission.physics.effects``, ``PropagationModel`` (composition,
the fast ``rss_dbm`` and the float64 ``explain`` reference) in ``mission.physics.model``; this
module holds the named models (``MODEL_NAMES``, aliases, ``make_model``) and re-exports the rest, so
``from mission.physics.propagation import make_model, PropagationModel, LegShadowing`` keeps
working.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import DTypeLike

from mission.physics.antenna import Pattern, load_pattern
from mission.physics.constants import (
    DEFAULT_BETA,
    DEFAULT_EPS_R,
    DEFAULT_FC_HZ,
    DEFAULT_PT_DBM,
    DEFAULT_SIGMA_S_M,
)
from mission.physics.effects import (
    Attitude,
    Effect,
    FreeSpace,
    GroundReflection,
    LegShadowing,
    Link,
    PathGainSlope,
    RxAntenna,
    TxAntenna,
)
from mission.physics.model import CHUNK, PropagationModel

__all__ = [
    "CHUNK",
    "MODEL_ALIASES",
    "MODEL_NAMES",
    "Attitude",
    "Effect",
    "FreeSpace",
    "GroundReflection",
    "LegShadowing",
    "Link",
    "PathGainSlope",
    "PropagationModel",
    "RxAntenna",
    "TxAntenna",
    "canonical_model_name",
    "make_model",
]


MODEL_NAMES = ("free-space", "two-ray", "e2r")
MODEL_ALIASES = {
    "fs": "free-space",
    "freespace": "free-space",
    "2ray": "two-ray",
    "tworay": "two-ray",
    "enhanced-two-ray": "e2r",
    "e-2ray": "e2r",
}


def canonical_model_name(name: str) -> str:
    """The model name ``make_model`` builds for ``name`` (case, underscores and aliases folded);
    ValueError for an unknown one.  CLIs use it as their argparse ``type`` so that they accept what
    ``make_model`` does."""
    key = str(name).strip().lower().replace("_", "-")
    key = MODEL_ALIASES.get(key, key)
    if key not in MODEL_NAMES:
        raise ValueError(f"unknown model {name!r}; choose one of {', '.join(MODEL_NAMES)}")
    return key


def make_model(
    name: str = "e2r",
    *,
    pattern: str | Pattern = "dipole",
    tx_pattern: str | Pattern | None = None,
    rx_pattern: str | Pattern | None = None,
    pt_dbm: float = DEFAULT_PT_DBM,
    fc_hz: float = DEFAULT_FC_HZ,
    eps_r: float = DEFAULT_EPS_R,
    sigma_s_m: float = DEFAULT_SIGMA_S_M,
    polarization: str = "V",
    beta: float = DEFAULT_BETA,
    rx_heading_rad: float = 0.0,
    rx_flipped: bool = False,
    tx_heading_rad: float = 0.0,
    tx_flipped: bool = False,
    dtype: DTypeLike = np.float32,
) -> PropagationModel:
    """Build "free-space", "two-ray" or "e2r" (enhanced two-ray = two-ray + attitude + leg
    shadowing).

    ``pattern`` ("dipole", "isotropic", "measured" = shipped RM-WB1-DN, a file path or a Pattern) is
    used for both ends unless ``tx_pattern``/``rx_pattern`` are given. Free space keeps the antenna
    gains (SPEC: P_r = P_t + G_t + G_r + 20 log10(lambda / (4 pi d_los))).
    """
    key = canonical_model_name(name)

    def _pat(p: str | Pattern | None) -> Pattern:
        p = pattern if p is None else p
        return p if isinstance(p, Pattern) else load_pattern(p)

    effects: list[Any] = [
        FreeSpace(pt_dbm=pt_dbm, fc_hz=fc_hz),
        TxAntenna(_pat(tx_pattern), heading_rad=tx_heading_rad, flipped=tx_flipped),
        RxAntenna(_pat(rx_pattern), heading_rad=rx_heading_rad, flipped=rx_flipped),
    ]
    if key in ("two-ray", "e2r"):
        effects.append(
            GroundReflection(eps_r=eps_r, sigma_s_m=sigma_s_m, polarization=polarization)
        )
    if key == "e2r":
        effects += [Attitude(), LegShadowing(beta=beta)]
    return PropagationModel(tuple(effects), name=key, dtype=dtype)
