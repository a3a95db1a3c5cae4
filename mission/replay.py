"""Replay a flight log: its summary (duration, samples, rate, altitude, RSS, attitude) and its path
by RSS.

Why: the first look at any flight, simulated or real, before localizing it: did it cover the area,
was the receiver delivering at the expected rate, did the attitude behave.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mission.files import save_figure
from mission.flightlog import FlightLog
from mission.localize.plot import draw_areas, field_areas, power_unit, robust_limits


def summary(log: FlightLog) -> dict[str, float | int | str]:
    """Key numbers of a flight log (NaN where a column is empty)."""
    t = log["t_s"]
    dur = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    rss, rel = log["rss_dbm"], log["rel_alt_m"]
    out: dict[str, float | int | str] = {
        "duration_s": dur,
        "samples": len(log),
        "rate_hz": (len(log) - 1) / dur if dur > 0 else float("nan"),
        "max_gap_s": float(np.max(np.diff(t))) if len(t) > 1 else float("nan"),
        "rel_alt_median_m": float(np.median(rel)),
        "rel_alt_max_m": float(np.max(rel)),
        "rss_min_db": float(np.min(rss)),
        "rss_max_db": float(np.max(rss)),
        "rss_median_db": float(np.median(rss)),
        "path_length_m": float(np.sum(np.linalg.norm(np.diff(log.enu()[:, :2], axis=0), axis=1))),
    }
    for c in ("roll_deg", "pitch_deg"):
        v = log[c][np.isfinite(log[c])]
        if len(v):
            p5, p95 = np.percentile(v, [5, 95])
            out[f"{c}_p5"], out[f"{c}_p95"] = float(p5), float(p95)
            out[f"{c}_absmax"] = float(np.max(np.abs(v)))
    src = log.meta.get("rss_source", {})
    out["rss_source"] = str(src.get("kind", "?"))
    out["status"] = str(log.meta.get("status", "?"))
    return out


def plot(log: FlightLog, png: Path) -> Path:
    """Path in ENU coloured by RSS (plus the true transmitter when known), saved as PNG (Agg
    backend)."""
    # matplotlib stays lazy (noqa): the Agg backend is chosen before pyplot loads, and runs
    # without a plot do not pay its import
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    enu = log.enu()
    fig, ax = plt.subplots(figsize=(7, 6))
    draw_areas(ax, field_areas(log))
    ax.plot(enu[:, 0], enu[:, 1], color="0.8", lw=0.6, zorder=1)
    # take-off outliers and deep nulls must not wash out the scale
    lo, hi = robust_limits(log["rss_dbm"])
    sc = ax.scatter(
        enu[:, 0], enu[:, 1], c=log["rss_dbm"], s=3, cmap="viridis", vmin=lo, vmax=hi, zorder=2
    )
    fig.colorbar(sc, ax=ax, label=f"RSS ({power_unit(log)}), 2-99.5 % range")
    i = int(np.argmax(log["rss_dbm"]))
    ax.plot(enu[i, 0], enu[i, 1], "r*", ms=14, label="strongest RSS", zorder=3)
    tx = log.truth_enu
    if tx is not None:
        ax.plot(tx[0], tx[1], "kx", ms=12, mew=2.5, label="true transmitter", zorder=3)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal")
    ax.legend(loc="best")
    ax.set_title(f"{log.label}: path coloured by RSS")
    fig.tight_layout()

    try:
        png = save_figure(fig, png, "--out", dpi=120)
    finally:
        plt.close(fig)
    return png
