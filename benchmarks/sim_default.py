"""Which network should answer a simulated log by default?  ``rfsl_default`` everywhere, or the
domain router (``mission/localize/sim_default.py``: a spiral network on simulated e2r dipole spirals
inside its altitudes).

Scored on the product path: ``rfsl simulate`` logs (take-off, return, landing, phase column) of
fresh seeds, then ``localize``'s default against ``--model rfsl_default.onnx`` on the same log; the
stop-20 rule in models/README.md.

    python benchmarks/sim_default.py --seeds 7000:7040 --workers 2        # 14 s on 2 cores
    python benchmarks/sim_default.py --seeds 7100:7130 --variants         # other spirals, 25 s
"""

from __future__ import annotations

import argparse
import contextlib
import os
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import yaml

from mission.cli.main import main as rfsl
from mission.localize.api import default_model_path, localize_log
from mission.threads import limit_worker

SETS = (
    ("spiral 30 m", "missions/spiral.yaml", None),
    ("spiral 45 m", "missions/spiral.yaml", 45.0),
    ("lawnmower 30 m", "missions/lawnmower.yaml", None),
)
# --variants: the spiral at 30 m with other generator parameters (the router matches generator and
# altitude only)
VARIANTS = (
    ("spacing 12 m", {"spacing_m": 12}),
    ("spacing 35 m", {"spacing_m": 35}),
    ("spacing 50 m", {"spacing_m": 50}),
    ("margin 30 m", {"margin_m": 30}),
    ("region flight", {"region": "flight"}),
    ("start nw", {"start": "nw"}),
)


def simulate_log(mission: str, out: str | Path, seed: int) -> Path:
    """``rfsl simulate`` one flight of ``mission`` (seed ``seed``) into a folder of ``out``,
    quietly; its log."""
    d = Path(out) / f"s{seed}_{Path(mission).stem}"
    # rfsl simulate's three lines per log
    with (
        open(os.devnull, "w") as null,
        contextlib.redirect_stdout(null),
    ):
        code = rfsl(["simulate", str(mission), "--seed", str(seed), "--out", str(d)])
    if code != 0:
        raise RuntimeError(f"rfsl simulate failed for {mission} seed {seed}")
    return next(d.glob("*.csv"))


def mission_variant(
    mission: str,
    folder: str | Path,
    label: str,
    alt: float | None = None,
    params: dict | None = None,
) -> str:
    """``mission`` itself, or a copy in ``folder`` flown at ``alt`` and/or with other generator
    ``params``."""
    if alt is None and params is None:
        return str(mission)
    spec = yaml.safe_load(Path(mission).read_text())
    spec["name"] = f"{Path(mission).stem}_{label.replace(' ', '_')}"
    spec["altitude_m"] = spec["altitude_m"] if alt is None else alt
    spec["trajectory"]["params"].update(params or {})
    spec["time_budget_s"] = (
        1500  # a denser spiral takes longer than the paper's 10 minutes (a check only)
    )
    out = Path(folder) / f"{spec['name']}.yaml"
    out.write_text(yaml.safe_dump(spec))
    return str(out)


def one(job: tuple[str, str, int]) -> tuple[float, float, str]:
    """(default's error, rfsl_default's error, default's model) on one simulated log (m)."""
    log = simulate_log(*job)
    a = localize_log(log)
    b = localize_log(log, model_path=default_model_path())
    return a.error_m, b.error_m, Path(a.extras.get("model_path", "?")).name


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="7000:7040", help="first:last (exclusive)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--variants", action="store_true", help="spirals with other generator parameters instead"
    )
    ap.add_argument(
        "--only", help="run only the sets whose label contains this text (e.g. 'spiral 30')"
    )
    args = ap.parse_args()

    lo, hi = (int(v) for v in args.seeds.split(":"))
    with (
        tempfile.TemporaryDirectory() as tmp,
        ProcessPoolExecutor(args.workers, initializer=limit_worker) as ex,
    ):
        sets = (
            [(label, "missions/spiral.yaml", None, p) for label, p in VARIANTS]
            if args.variants
            else [(*s, None) for s in SETS]
        )
        sets = [s for s in sets if args.only is None or args.only in s[0]]
        for label, mission, alt, params in sets:
            mission = mission_variant(mission, tmp, label, alt, params)
            out = tempfile.mkdtemp(dir=tmp)
            rows = list(ex.map(one, [(mission, out, s) for s in range(lo, hi)]))
            a, b = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
            used = {m: sum(r[2] == m for r in rows) for m in dict.fromkeys(r[2] for r in rows)}
            print(
                f"{label} (n={len(rows)}): default {a.mean():.1f} / {np.median(a):.1f} / "
                f"{np.percentile(a, 90):.1f}  "
                f"rfsl_default {b.mean():.1f} / {np.median(b):.1f} / "
                f"{np.percentile(b, 90):.1f}  models {used}",
                flush=True,
            )


if __name__ == "__main__":
    main()
