"""What a pipeline's fitted parameters are, in words and numbers (for the report and ``gap.json``).

Why a module of its own: the fitting (``fit``), the candidates and the diagnosis all describe
pipelines, and the candidates build on the free-form and smoother modules; a description that lives
below all of them keeps the imports one-way.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mission.gap.pipeline import Pipeline
from mission.gap.spatial import KrigedShadowing
from mission.physics.antenna import Dipole, Isotropic, Pattern
from mission.physics.shadowing import RandomField


def pattern_name(p: Pattern) -> str:
    """isotropic | dipole | measured (any tabulated pattern)."""
    if isinstance(p, Isotropic):
        return "isotropic"
    if isinstance(p, Dipole):
        return "dipole"
    return "measured"


def describe_params(p: Pipeline) -> dict[str, Any]:
    """The current values of every parameter the library can fit (for the report)."""
    m = p.model
    out: dict[str, Any] = {"effects": list(p.components())}
    for end in ("rx", "tx"):
        if m.has(f"{end}_antenna"):
            e = m.effect(f"{end}_antenna")
            out[f"{end}_pattern"] = pattern_name(e.pattern) + (" flipped" if e.flipped else "")
            out[f"{end}_heading_deg"] = float(np.rad2deg(e.heading_rad)) % 360.0
    if m.has("tx_tilt"):
        t = m.effect("tx_tilt")
        out["tx_tilt_deg"], out["tx_tilt_azimuth_deg"] = t.tilt_deg, t.azimuth_deg
    if m.has("ground_reflection"):
        g = m.effect("ground_reflection")
        out.update(eps_r=g.eps_r, sigma_s_m=g.sigma_s_m, polarization=g.polarization)
    if m.has("attitude"):
        out["attitude"] = "roll, pitch, yaw" if m.effect("attitude").roll_pitch else "yaw only"
    if m.has("path_gain_slope"):
        out["path_gain_n_extra"] = m.effect("path_gain_slope").n_extra
    if m.has("leg_shadowing"):
        ls = m.effect("leg_shadowing")
        out.update(beta=ls.beta, half_width_deg=ls.half_width_deg, legs_deg=list(ls.legs_deg))
    out["time_offset_s"] = p.time_offset_s
    if p.receiver is not None:
        out.update(floor_db=p.receiver.floor_db, sat_db=p.receiver.sat_db)
    if isinstance(p.spatial, KrigedShadowing | RandomField):
        out.update(spatial_sigma_db=p.spatial.sigma_db, spatial_corr_len_m=p.spatial.corr_len_m)
    return out
