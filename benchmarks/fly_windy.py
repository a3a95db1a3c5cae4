"""The fixed spiral (or the adaptive mission, ``--arm``) on ArduCopter SITL in wind, for the
budget watch's pace fit (replay the logs with ``replay_pace.py``).

    python benchmarks/fly_windy.py --wind 8 250 3 --seeds 40 41 42 43 --out /tmp/windy
    python benchmarks/replay_pace.py /tmp/windy/ardupilot_fixed_*/flights/*/flight.csv

Why: a real field has wind, and a multicopter flies its upwind legs slower than planned and its
downwind legs on plan, which a pace without the legs' directions reads as outliers or as a cost per
leg.  ArduPilot's SITL simulates wind (``SIM_WIND_SPD`` m/s, ``SIM_WIND_DIR`` the direction it
comes from, degrees, ``SIM_WIND_TURB`` m/s of turbulence); ../shared/sitl/ardupilot/start.sh has no
hook for parameters and ../shared is read-only, so this writes a start script of its own into
``OUT``: the shared script's command line with a third defaults file holding the wind.  Each flight
is ``bench_sitl_seeds.fly_one`` (20x, ``fly-mission --seed N``), one JSON line per flight appended
to ``OUT/flights.jsonl``.

Flown 2026-11-29 (docs/flying.md): 8 m/s from 250 deg, turbulence 3 (seeds 40-43); 6 m/s from 30
deg, turbulence 2 (44-47); 9 m/s from 140 deg, turbulence 3 (48-51).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sitl_seeds import SHARED, fly_one  # noqa: E402

# ../shared/sitl/ardupilot/start.sh's command line, with the wind's defaults file third
START = """#!/bin/bash
HERE={here}
SPEEDUP=${{1:-5}}; I=${{2:-0}}; HOME_LOC=${{3:-35.72737,-78.69622,0,0}}
RUN=${{RUN:-/tmp/ardupilot-sitl$I}}; mkdir -p "$RUN"; cd "$RUN" || exit 1
nohup "$HERE/arducopter" --model quad --speedup "$SPEEDUP" --home "$HOME_LOC" \\
  --defaults "$HERE/copter.parm,$HERE/streams.parm,{wind}" -I"$I" -w \\
  > "$RUN/sitl.log" 2>&1 < /dev/null &
echo $!
"""


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wind", nargs=3, type=float, required=True, metavar=("MPS", "FROM", "TURB"))
    ap.add_argument("--seeds", nargs="+", type=int, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--instance", type=int, default=5)
    ap.add_argument("--arm", choices=("fixed", "adaptive"), default="fixed", help="the mission")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    spd, frm, turb = args.wind
    wind = args.out / "wind.parm"
    wind.write_text(f"SIM_WIND_SPD {spd:g}\nSIM_WIND_DIR {frm:g}\nSIM_WIND_TURB {turb:g}\n")
    script = args.out / "start.sh"
    script.write_text(START.format(here=SHARED / "ardupilot", wind=wind.resolve()))
    script.chmod(0o755)
    for seed in args.seeds:
        row = fly_one("ardupilot", args.arm, seed, args.out, args.instance, script=script)
        row["wind"] = [spd, frm, turb]
        with open(args.out / "flights.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")
        print(f"seed {seed}: exit {row['rc']}, {row.get('flight_s')} s, {row.get('error_m')} m")


if __name__ == "__main__":
    main()
