"""Which shipped network answers a *simulated* log by default: the one trained on that kind of
flight.

Why: ``rfsl_default`` was trained across trajectories and altitudes (20-47 m) and is the safe answer
for any simulated mission, but on the product's own job, the paper's spiral flown with the default
e2r dipole source, the spiral specialists are 2-3x better: the five-member spiral ensemble
``rfsl_spiral_e2r_ens5`` errs 5.1 m mean, 4.3 m median on 200 ``rfsl simulate`` spirals at 30 m
against 16.3 / 15.3 m (``benchmarks/sim_default.py``), and ``rfsl_spiral_alt`` stays at 7-9 m on
spirals flown at 20-55 m, where ``rfsl_default`` errs 15-50 m (models/README.md).  A network is
chosen only when the log's sidecar says it is inside that network's training domain (trajectory
generator, source physics, and cruise altitude within ``training_domain``'s tolerance); any other
simulated log keeps ``rfsl_default``.  Real receiver logs never come here (they get the fusion).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mission.localize.card import training_domain_of
from mission.localize.training_domain import (
    CIRCLE_ATTITUDE_TOLERANCE_DEG,
    altitude_note,
    attitude_note,
    flight_altitudes,
)
from mission.shipped import shipped_model

# the most specialised first
SPIRAL_NETWORKS = (
    "rfsl_spiral_e2r_ens5.onnx",
    "rfsl_spiral_alt.onnx",
)
# trained on spirals flown nose down (0.6-6 deg of pitch per m/s: -3 to -35 deg at 5.5 m/s): answers
# a spiral whose attitude leaves the chosen level network's training attitudes (ArduCopter SITL
# cruises at about -14 deg, PX4 SITL at -28; benchmarks/score_tilt_network.py)
TILT_NETWORK = "rfsl_spiral_tilt.onnx"
SPIRAL_SOURCE_MODEL = "e2r"
# model_params keys that would change the dipole default
DIPOLE_KEYS = (
    "pattern",
    "tx_pattern",
    "rx_pattern",
)


def spiral_source(meta: dict) -> str | None:
    """Why a simulated log is *not* the spiral networks' kind of flight (None when it is): its
    sidecar must record the spiral generator (``trajectory.generator``) and an e2r source with
    dipole patterns."""
    traj = meta.get("trajectory") or {}
    if traj.get("generator") != "spiral":
        gen = traj.get("generator")
        return f"trajectory {gen}" if gen else "no trajectory in the sidecar"
    src = meta.get("rss_source") or {}
    if src.get("model") != SPIRAL_SOURCE_MODEL:
        return f"source model {src.get('model')}"
    params = src.get("model_params") or {}
    pats = {str(params[k]) for k in DIPOLE_KEYS if k in params}
    if pats - {"dipole"}:
        return f"antenna pattern {', '.join(sorted(pats - {'dipole'}))}"
    return None


def sim_default_model(
    meta: dict,
    heights_m: np.ndarray,
    default: Path | None,
    attitude_deg: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> tuple[Path | None, str]:
    """(network path, why) for a simulated log with sidecar ``meta`` whose used samples fly at
    ``heights_m`` with roll and pitch spans ``attitude_deg`` (``flight_attitude``): the first
    spiral network whose training altitudes hold the flight (the tilt network instead when the
    flown attitude leaves that one's training attitudes and lies inside its own), else ``default``
    (``rfsl_default``)."""
    dname = default.name if default is not None else "none"
    why_not = spiral_source(meta)
    if why_not is not None:
        return default, f"default model {dname} ({why_not}: not a spiral network's flight)"
    flown = flight_altitudes(heights_m)
    for name in SPIRAL_NETWORKS:
        path = shipped_model(name)
        if path is None:
            continue
        dom = training_domain_of(path)
        trained = dom.altitude_m
        if trained is not None and altitude_note(name, trained, flown) is None:
            tilted = tilt_alternative(name, dom.attitude_deg, flown, attitude_deg, TILT_NETWORK)
            if tilted is not None:
                return tilted
            return path, (
                f"model {name}: a simulated e2r spiral at {np.median(heights_m):.0f} m, the "
                "kind of "
                f"flight it was trained on (spiral, dipoles, {trained[0]:.0f}-{trained[1]:.0f} m)"
            )
    return default, (
        f"default model {dname} (spiral at {np.median(heights_m):.0f} m: outside the spiral "
        "networks' altitudes)"
    )


def outside_training_attitudes(name: str, trained_attitude, attitude_deg) -> bool:
    """Whether the flown attitude ``attitude_deg`` leaves network ``name``'s training attitudes
    (no tolerance, as for its circles; False where either is unknown): the test that hands a
    flight to the tilt network."""
    if attitude_deg is None or trained_attitude is None:
        return False
    return (
        attitude_note(name, trained_attitude, attitude_deg, CIRCLE_ATTITUDE_TOLERANCE_DEG)
        is not None
    )


def tilt_alternative(
    name: str, trained_attitude, flown_altitude, attitude_deg, tilt_name: str
) -> tuple[Path, str] | None:
    """(path, why) of the network ``tilt_name`` (trained on nose-down cruise) when the flown
    attitude ``attitude_deg`` leaves network ``name``'s training attitudes (no tolerance, as for its
    circles) and ``tilt_name``'s training holds the flight's altitude and attitude; None otherwise
    (``name`` answers)."""
    if not outside_training_attitudes(name, trained_attitude, attitude_deg):
        return None
    path = shipped_model(tilt_name)
    if path is None:
        return None
    dom = training_domain_of(path)
    if dom.altitude_m is None or altitude_note(tilt_name, dom.altitude_m, flown_altitude):
        return None
    if dom.attitude_deg is None or outside_training_attitudes(
        tilt_name, dom.attitude_deg, attitude_deg
    ):
        return None
    pitch = attitude_deg[1]
    lo = dom.attitude_deg[1][0]
    return path, (
        f"model {tilt_name}: flown at {pitch[0]:.0f} to {pitch[1]:.0f} deg of pitch, outside "
        f"{name}'s training attitudes and inside this network's (flown nose down to {lo:.0f} deg)"
    )
