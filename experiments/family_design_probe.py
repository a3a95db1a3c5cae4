"""Is the benchmark hard for the reason the real flights are?  The fitted physics family on flights
designed like the AFAR ones, with parts of its physics taken away.

Why: the benchmark's flights are about twice as hard as the six real ones for every localizer, and
its pooled decisions (models/README.md, issue 32) weigh them as much as the real flights.  The
unseen suite draws the flight design broadly (altitude 15-60 m, speed 2-10 m/s, 35-100 % of a path,
four heading habits); the AFAR flights flew 27-37 m high at 2.5-6 m/s, whole paths, nose fixed at
300-360 deg most of the time.  ``--design afar`` redraws those axes so (after the suite's own draw,
from a separate generator, so the physics and the transmitter are the suite's); ``--shadowing-db``,
``--isotropic`` and ``--no-slope`` take parts of the family's physics away.  Printed: the mean error
of the default (fusion), selfcal and the spiral network, where the transmitter lies inside the flown
area (with its 90 % bootstrap interval over flights) and outside it (real flights inside: 21.4 /
27.0 / 38.0 m).

    python experiments/family_design_probe.py --n 60 --design afar          # ~1 min on 2 cores
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mission.evidence import mean_interval
from mission.flightlog import FlightLog
from mission.localize.api import localize_log
from mission.localize.classical import as_flight
from mission.localize.preprocess import select_samples
from mission.localize.selfcal import flown_area
from mission.workshop import suite

MEMBERS = {
    "fusion": {"method": "fusion"},
    "selfcal": {"method": "selfcal"},
    "rfsl_spiral_e2r": {"model_path": "models/rfsl_spiral_e2r.onnx"},
}


def afar_design(d: dict, i: int) -> None:
    """Redraw flight ``i``'s design axes like the AFAR 2023 flights (module docstring)."""
    r = np.random.default_rng([77, i])
    d["altitude_m"], d["speed_mps"] = r.uniform(27, 37), r.uniform(2.5, 6)
    d["keep_fraction"], d["budget_s"] = r.uniform(0.9, 1.0), 720.0
    fixed = r.uniform() < 0.75
    d["heading_habit"] = "fixed" if fixed else "along_track"
    d["fixed_heading_deg"] = r.uniform(300, 360)


def family_file(args, out: Path) -> str:
    """The family with the parts ``args`` take away, written to ``out`` (or the family as given)."""
    if args.shadowing_db is None and not args.isotropic and not args.no_slope:
        return args.family
    d = json.loads(Path(args.family).read_text())
    if args.shadowing_db is not None:
        sh = d["residual"]["shadowing_db"]
        sh["sd"] = sh["sd"] * args.shadowing_db / sh["mean"]
        sh["mean"] = args.shadowing_db
    if args.isotropic:
        for v in d["variants"]:
            v["spec"]["rx_pattern"] = v["spec"]["tx_pattern"] = "isotropic"
    if args.no_slope:
        d["spec"]["path_gain_slope"] = {"dist": "normal", "mean": 0.0, "sd": 0.0}
    d["name"] = d["name"] + "-probe"
    out.write_text(json.dumps(d))
    return str(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--n", type=int, default=60, help="benchmark flights (seed 2026) 0..n-1")
    ap.add_argument("--family", default="mission/data/afar_family.json")
    ap.add_argument("--design", choices=("unseen", "afar"), default="afar")
    ap.add_argument("--shadowing-db", type=float, default=None, help="shadowing sill mean, dB")
    ap.add_argument("--isotropic", action="store_true", help="isotropic UAV and rover antennas")
    ap.add_argument("--no-slope", action="store_true", help="free-space path loss (slope 0)")
    ap.add_argument("--out", default="/tmp/family_probe.json", help="the modified family")
    args = ap.parse_args()
    fam = family_file(args, Path(args.out))
    err: dict[str, list[float]] = {m: [] for m in MEMBERS}
    inside = []
    for i in range(args.n):
        d, rng = suite.draw_flight(suite.BENCHMARK_SEED, i, fam)
        if args.design == "afar":
            afar_design(d, i)
        cols, _, _ = suite.simulate_draw(d, rng)
        log = FlightLog(cols, suite._meta(d))
        t = np.array(d["tx_xy"])
        for m, kw in MEMBERS.items():
            e = localize_log(log, **kw)
            err[m].append(float(np.hypot(e.x_m - t[0], e.y_m - t[1])))
        part, _ = select_samples(log)
        inside.append(bool(flown_area(as_flight(part, log.origin).enu_m).contains(t[None])[0]))
    ins = np.array(inside)
    print(f"{args.n} flights, design {args.design}, family {fam}")
    print(f"{ins.sum()} with the transmitter inside the flown area; mean error m:")
    for m, e in err.items():
        e = np.array(e)
        print(
            f"  {m:16s} all {e.mean():5.1f}  inside {mean_interval(e[ins]).fmt()}  "
            f"outside {e[~ins].mean():5.1f}"
        )


if __name__ == "__main__":
    main()
