"""How well the simulated RSS source explains a SITL flight at its true transmitter, with the logged
attitude and with the body taken level.

Why: the adaptive answer's judge (``rounds_answer.physics_rms_db``) found every candidate of
some SITL flights 9-17 dB from the mission's physics.  If the physics at the truth explains the
flight to its noise, the failure is that no candidate lies near the truth, not a mismatched
judge; the level-body figure says how much the cruise pitch (ArduCopter -14 deg, PX4 -28 deg)
moves the RSS.

    python experiments/sitl_physics_residual.py D/flights.jsonl   # a bench_sitl_seeds store
"""

from __future__ import annotations

import json
import sys

import numpy as np

from mission.flightlog import read_flight_log
from mission.localize.rounds_answer import offset_residual
from mission.physics import make_model


def main(store: str) -> None:
    for line in open(store).read().splitlines():
        r = json.loads(line)
        if not r.get("log"):
            continue
        log = read_flight_log(r["log"])
        s, src = log.samples(), log.meta["rss_source"]
        model = make_model(src["model"], **(src.get("model_params") or {}))
        rms = [
            float(
                np.sqrt(
                    np.mean(
                        offset_residual(s.rss_dbm, model.rss_dbm(log.truth_enu, s.enu_m, a)) ** 2
                    )
                )
            )
            for a in (s.attitude_rad, np.zeros_like(s.attitude_rad))
        ]
        pitch = float(np.degrees(np.median(s.attitude_rad[:, 1])))
        print(
            f"{r['autopilot']:9s} {r['arm']:8s} seed {r['seed']:2d}: at the truth {rms[0]:5.2f} dB "
            f"with the logged attitude, {rms[1]:5.2f} dB level (median pitch {pitch:+.1f} deg)"
        )


if __name__ == "__main__":
    main(sys.argv[1])
