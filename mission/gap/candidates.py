"""The effect library: named, parameterised candidate effects that the diagnosis tries one at a
time.

Why: "which effect is missing?" is answered by adding each candidate to the current model, fitting
its parameters on training blocks and measuring the held-out gap (``mission.gap.fit``).  Each
candidate knows (a) whether it can be tried on a pipeline, (b) how to build the pipeline for given
parameter values, (c) its parameter bounds and a coarse start grid (angles are multimodal), and (d)
how to *withhold* it from a truth pipeline (for the self-test).  A candidate whose effect is already
in the model *refits* it (e.g. the ground permittivity of an e2r base); one that is absent *adds*
it.

| name | what | parameters |
| --- | --- | --- |
| ``rx_pattern`` | UAV antenna: isotropic, dipole, measured RM-WB1-DN, upside down | choice |
| ``rx_mounting`` | UAV antenna heading from the nose (azimuthal pattern, attitude) | heading_deg |
| ``tx_pattern`` | rover antenna (isotropic, dipole, measured, measured upside down) | choice |
| ``tx_mounting`` | rover antenna heading (needs an azimuth-dependent pattern) | heading_deg |
| ``tx_tilt`` | rover dipole tilted off vertical | tilt_deg, azimuth_deg |
| ``ground_reflection`` | ground-reflected ray, Fresnel Gamma | eps_r, sigma_s_m, polarization |
| ``attitude`` | receiver angles in the body frame; also on top of yaw-only | heading_deg (*) |
| ``yaw_attitude`` | receiver angles in a frame turned by the yaw only (level) | heading_deg (*) |
| ``path_gain_slope`` | extra path-gain exponent, -10 n_extra log10(d / 100 m) | n_extra |
| ``leg_shadowing`` | paper eqs. 8-9 (3 or 4 legs: ``LEG_LAYOUTS``) | beta, half width, rotation |
| ``near_nadir`` | body-fixed loss over depression angles (``gap.nadir``) | depth, centre, width |
| ``time_offset`` | RSS lags telemetry by tau | tau_s |
| ``receiver`` | soft noise floor and saturation | floor_db, sat_db (model dB scale) |
| ``rx_gain_map`` | free-form: smooth UAV body-frame gain map (``gap.freeform``) | ridge coefs |
| ``tx_gain_map`` | free-form: smooth rover gain map, compass azimuth x elevation | ridge coefs |
| ``excess_loss`` | free-form: smooth excess loss over distance and UAV height | ridge coefs |
| ``time_drift`` | free-form: a gain drifting / stepping in a flight (``temporal``) | ridge coefs |
| ``spatial_shadowing`` | smoother: kriged residuals (``gap.spatial``) | sigma_db, corr_len_m |
| ``site_map`` | smoother: per rover position, azimuth x log distance (``spatial``) | ridge coefs |

(*) the UAV antenna heading is fitted jointly with the (yaw) attitude when the UAV pattern depends
on azimuth: without yaw a heading is a fixed compass direction, with yaw and a wrong heading the
pattern is turned wrongly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from mission.errors import InputError
from mission.gap.candidate import Candidate, Param
from mission.gap.describe import pattern_name
from mission.gap.freeform import FREEFORM_NAMES, freeform_candidate
from mission.gap.nadir import near_nadir_candidate
from mission.gap.pipeline import Pipeline, Receiver, TxTilt
from mission.gap.spatial import site_map_candidate, spatial_candidate
from mission.gap.temporal import time_candidate
from mission.physics import (
    Attitude,
    GroundReflection,
    LegShadowing,
    PathGainSlope,
    RxAntenna,
    TxAntenna,
)
from mission.physics.antenna import Dipole, Isotropic, Pattern, rm_wb1_dn
from mission.physics.constants import LEG_AZIMUTHS_DEG

PATTERN_NAMES = ("isotropic", "dipole", "measured")


def pattern_by_name(name: str) -> Pattern:
    """isotropic | dipole | measured (shipped RM-WB1-DN); any other name raises ``InputError``."""
    makers = {"isotropic": Isotropic, "dipole": Dipole, "measured": rm_wb1_dn}
    if name not in makers:
        raise InputError(
            f"unknown antenna pattern {name!r} (expected {', '.join(PATTERN_NAMES)})",
            field="pattern",
        )
    return makers[name]()


# -------------------------------------------------------------------------------------------
# antennas

_PATTERN_CHOICES = (
    {"pattern": "isotropic", "flipped": False},
    {"pattern": "dipole", "flipped": False},
    {"pattern": "measured", "flipped": False},
    {"pattern": "measured", "flipped": True},
)


def _antenna_pattern_candidate(end: str) -> Candidate:
    cls = RxAntenna if end == "rx" else TxAntenna
    eff = f"{end}_antenna"

    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        cur = p.model.effect(eff) if p.model.has(eff) else cls()
        e = replace(cur, pattern=pattern_by_name(ch["pattern"]), flipped=bool(ch["flipped"]))
        return p.replace(model=p.model.with_effect(e))

    def choices(p: Pipeline) -> Sequence[dict[str, Any]]:
        cur = p.model.effect(eff) if p.model.has(eff) else None
        now = None if cur is None else (pattern_name(cur.pattern), bool(cur.flipped))
        return tuple(c for c in _PATTERN_CHOICES if (c["pattern"], c["flipped"]) != now)

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(
            model=p.model.with_effect(
                replace(p.model.effect(eff), pattern=Isotropic(), flipped=False)
            )
        )

    who = "UAV" if end == "rx" else "rover"
    return Candidate(
        f"{end}_pattern",
        f"{who} antenna pattern (isotropic, dipole, measured, upside down)",
        (),
        build,
        lambda p: True,
        withhold,
        choices,
    )


HEADING_PARAM = Param(
    "heading_deg", 0.0, 360.0, tuple(np.arange(0.0, 360.0, 20.0)), period=360.0, unit="deg"
)


def _antenna_mounting_candidate(end: str) -> Candidate:
    eff = f"{end}_antenna"

    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        e = replace(p.model.effect(eff), heading_rad=float(np.deg2rad(th["heading_deg"])))
        return p.replace(model=p.model.with_effect(e))

    def applicable(p: Pipeline) -> bool:
        # the UAV antenna's heading is relative to the nose: meaningless unless the model turns the
        # body by the logged yaw (attitude or yaw_attitude); the rover's frame is fixed (forward =
        # north)
        return (
            p.model.has(eff)
            and not p.model.effect(eff).pattern.azimuth_symmetric
            and (end == "tx" or p.model.has("attitude"))
        )

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.with_params(eff, heading_rad=0.0))

    who = "UAV" if end == "rx" else "rover"
    return Candidate(
        f"{end}_mounting",
        f"{who} antenna heading offset",
        (HEADING_PARAM,),
        build,
        applicable,
        withhold,
    )


def _tx_tilt_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p.replace(
            model=p.model.with_effect(TxTilt(th["tilt_deg"], th["azimuth_deg"] % 360.0))
        )

    def applicable(p: Pipeline) -> bool:
        return p.model.has("tx_antenna") and isinstance(
            p.model.effect("tx_antenna").pattern, Dipole
        )

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without("tx_tilt")) if p.model.has("tx_tilt") else p

    return Candidate(
        "tx_tilt",
        "rover dipole tilted off vertical",
        (
            Param("tilt_deg", 0.0, 60.0, (10.0, 25.0, 40.0), unit="deg"),
            Param(
                "azimuth_deg",
                0.0,
                360.0,
                tuple(np.arange(0.0, 360.0, 45.0)),
                period=360.0,
                unit="deg",
            ),
        ),
        build,
        applicable,
        withhold,
    )


# -------------------------------------------------------------------------------------------
# channel


def _ground_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        g = GroundReflection(
            eps_r=float(10 ** th["log10_eps_r"]),
            sigma_s_m=float(10 ** th["log10_sigma"]),
            polarization=ch["polarization"],
        )
        return p.replace(model=p.model.with_effect(g))

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without("ground_reflection"))

    return Candidate(
        "ground_reflection",
        "ground-reflected ray (permittivity, conductivity, polarisation)",
        (
            Param("log10_eps_r", 0.05, 1.9, (0.3, 0.7, 1.0, 1.3, 1.6)),
            Param("log10_sigma", -4.0, -0.5, (-3.0, -2.0)),
        ),
        build,
        lambda p: True,
        withhold,
        lambda p: ({"polarization": "V"}, {"polarization": "H"}),
    )


def _rx_azimuthal(p: Pipeline) -> bool:
    return p.model.has("rx_antenna") and not p.model.effect("rx_antenna").pattern.azimuth_symmetric


def _attitude_like_candidate(roll_pitch: bool) -> Candidate:
    """``attitude`` (roll, pitch, yaw) or ``yaw_attitude`` (yaw only, body level).

    Adding the body frame makes the UAV antenna's heading relative to the nose meaningful, and a
    wrong heading can make the yaw look useless (and vice versa: a heading without yaw is a fixed
    compass direction), so when the UAV pattern depends on azimuth the candidate fits that heading
    jointly (``heading_deg``). ``attitude`` also applies on top of yaw-only attitude (does
    roll/pitch add anything?).
    """

    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        m = p.model.with_effect(Attitude(roll_pitch=roll_pitch))
        if "heading_deg" in th:
            m = m.with_params("rx_antenna", heading_rad=float(np.deg2rad(th["heading_deg"])))
        return p.replace(model=m)

    def applicable(p: Pipeline) -> bool:
        if not p.model.has("attitude"):
            return True
        return roll_pitch and not p.model.effect("attitude").roll_pitch

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without("attitude")) if p.model.has("attitude") else p

    def params_of(p: Pipeline) -> tuple[Param, ...]:
        return (HEADING_PARAM,) if _rx_azimuthal(p) else ()

    if roll_pitch:
        return Candidate(
            "attitude",
            "receiver gains in the body frame (logged roll, pitch, yaw; + UAV antenna heading)",
            (HEADING_PARAM,),
            build,
            applicable,
            withhold,
            params_of=params_of,
        )
    return Candidate(
        "yaw_attitude",
        "receiver gains in a frame turned by the logged yaw only (body level; + UAV "
        "antenna heading)",
        (HEADING_PARAM,),
        build,
        applicable,
        withhold,
        params_of=params_of,
    )


def _path_gain_slope_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p.replace(
            model=p.model.with_effect(PathGainSlope(n_extra=float(th["n_extra"]), d_ref_m=100.0))
        )

    def withhold(p: Pipeline) -> Pipeline:
        return (
            p.replace(model=p.model.without("path_gain_slope"))
            if p.model.has("path_gain_slope")
            else p
        )

    return Candidate(
        "path_gain_slope",
        "extra path-gain exponent: -10 n_extra log10(d / 100 m)",
        (Param("n_extra", -1.5, 5.0, (-0.5, 0.5, 1.5, 3.0)),),
        build,
        lambda p: not p.model.has("path_gain_slope"),
        withhold,
    )


# leg layouts the legs candidate tries: the paper's three legs, and a quad's four (an X, 90 deg
# apart)
LEG_LAYOUTS: dict[str, tuple[float, ...]] = {
    "paper": tuple(LEG_AZIMUTHS_DEG),
    "quad": (45.0, 135.0, 225.0, 315.0),
}


def _legs_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        base = LEG_LAYOUTS[ch.get("layout", "paper")]
        legs = tuple(float((a + th["legs_rotation_deg"]) % 360.0) for a in base)
        e = LegShadowing(
            beta=float(th["beta"]), legs_deg=legs, half_width_deg=float(th["half_width_deg"])
        )
        return p.replace(model=p.model.with_effect(e))

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without("leg_shadowing"))

    return Candidate(
        "leg_shadowing",
        "UAV leg shadowing, paper eqs. 8-9",
        (
            Param("beta", 0.0, 8.0, (0.3, 1.0, 2.5)),
            Param("half_width_deg", 1.0, 25.0, (3.0, 6.0, 12.0, 20.0), unit="deg"),
            Param(
                "legs_rotation_deg",
                -60.0,
                60.0,
                (-45.0, -30.0, -15.0, -5.0, 0.0, 5.0, 15.0, 30.0, 45.0),
                unit="deg",
            ),
        ),
        build,
        lambda p: p.model.has("attitude"),
        withhold,
        lambda p: ({"layout": "paper"}, {"layout": "quad"}),
    )


# ------------------------------------------------------------------------------------ around the
# channel


def _time_offset_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p.replace(time_offset_s=float(th["tau_s"]))

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(time_offset_s=0.0)

    return Candidate(
        "time_offset",
        "RSS lags the telemetry by tau",
        (Param("tau_s", -4.0, 4.0, tuple(np.arange(-3.0, 3.01, 0.5)), unit="s"),),
        build,
        lambda p: True,
        withhold,
    )


def _receiver_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p.replace(receiver=Receiver(float(th["floor_db"]), float(th["sat_db"])))

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(receiver=None)

    # bounds are relative to the model's dB scale; fit.py rescales them to the data (see
    # ``relative``)
    return Candidate(
        "receiver",
        "receiver noise floor and saturation",
        (Param("floor_db", -200.0, 0.0, ()), Param("sat_db", -200.0, 0.0, ())),
        build,
        lambda p: p.receiver is None,
        withhold,
        post_only=True,
    )


# -------------------------------------------------------------------------------------------
# library


def library() -> dict[str, Candidate]:
    """Every candidate effect by name (the order is the report's order)."""
    named = [
        _antenna_pattern_candidate("rx"),
        _antenna_mounting_candidate("rx"),
        _antenna_pattern_candidate("tx"),
        _antenna_mounting_candidate("tx"),
        _tx_tilt_candidate(),
        _ground_candidate(),
        _attitude_like_candidate(True),
        _attitude_like_candidate(False),
        _legs_candidate(),
        near_nadir_candidate(),
        _path_gain_slope_candidate(),
        _time_offset_candidate(),
        _receiver_candidate(),
    ]
    # what a free-form map is compared with (``freeform.resemblance``)
    refs = {c.name: c for c in named}
    cands = [
        *named,
        *(freeform_candidate(k, refs) for k in FREEFORM_NAMES),
        time_candidate(),
        spatial_candidate(),
        site_map_candidate(),
    ]
    return {c.name: c for c in cands}


def select(names: str | Sequence[str] | None) -> list[Candidate]:
    """Candidates by comma-separated names or ``all``; unknown names raise ``InputError``."""
    lib = library()
    if names is None or names == "all":
        return list(lib.values())
    lst = [n.strip() for n in names.split(",")] if isinstance(names, str) else list(names)
    bad = [n for n in lst if n not in lib]
    if bad:
        raise InputError(
            f"unknown candidate(s) {', '.join(bad)} (expected {', '.join(lib)} or all)",
            field="candidates",
        )
    return [lib[n] for n in lst]
