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

from mission.localize.training_domain import altitude_note, flight_altitudes
from mission.shipped import shipped_model

# the most specialised first
SPIRAL_NETWORKS = (
    "rfsl_spiral_e2r_ens5.onnx",
    "rfsl_spiral_alt.onnx",
)
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
    meta: dict, heights_m: np.ndarray, default: Path | None
) -> tuple[Path | None, str]:
    """(network path, why) for a simulated log with sidecar ``meta`` whose used samples fly at
    ``heights_m``: the first spiral network whose training altitudes hold the flight, else
    ``default`` (``rfsl_default``)."""
    dname = default.name if default is not None else "none"
    why_not = spiral_source(meta)
    if why_not is not None:
        return default, f"default model {dname} ({why_not}: not a spiral network's flight)"
    # onnxruntime stays lazy (noqa): a simulated spiral's route only; localize --method grid and
    # the classical routes start without it
    from mission.localize.onnx_model import OnnxLocalizer  # noqa: PLC0415

    flown = flight_altitudes(heights_m)
    for name in SPIRAL_NETWORKS:
        path = shipped_model(name)
        if path is None:
            continue
        trained = OnnxLocalizer(path, threads=1).card.domain.altitude_m
        if trained is not None and altitude_note(name, trained, flown) is None:
            return path, (
                f"model {name}: a simulated e2r spiral at {np.median(heights_m):.0f} m, the "
                "kind of "
                f"flight it was trained on (spiral, dipoles, {trained[0]:.0f}-{trained[1]:.0f} m)"
            )
    return default, (
        f"default model {dname} (spiral at {np.median(heights_m):.0f} m: outside the spiral "
        "networks' altitudes)"
    )
