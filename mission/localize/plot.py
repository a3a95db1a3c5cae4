"""Plot a localization: the flight coloured by smoothed RSS, the 3D clusters and their top-n_t samples,
the estimate and (when known) the truth.  matplotlib with the Agg backend (no display needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mission.localize import Estimate
from mission.localize.features import FeatureConfig, cluster_details


def plot_localization(
    log, est: Estimate, out: str | Path, cfg: FeatureConfig | None = None, area=None, title: str | None = None
) -> Path:
    """Draw ``log`` (its cruise part, positions in the log's frame) with ``est``; writes ``out`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg = cfg or FeatureConfig()
    enu = log.enu()
    cr = cluster_details(enu[:, 0], enu[:, 1], log["rss_dbm"], cfg)
    fig, ax = plt.subplots(figsize=(8.5, 7.5), dpi=120)
    if area is not None:
        v = np.vstack([area.vertices, area.vertices[:1]])
        ax.plot(v[:, 0], v[:, 1], "--", color="0.5", lw=1, label=area.name)
    sc = ax.scatter(cr.x, cr.y, c=cr.p - cr.p.max(), s=3, cmap="viridis", zorder=1)
    fig.colorbar(sc, ax=ax, label="smoothed RSS relative to max (dB)", shrink=0.8)
    cmap = plt.get_cmap("tab20")
    t = cr.top
    ax.scatter(
        cr.x[t],
        cr.y[t],
        s=16,
        facecolors="none",
        edgecolors=cmap(cr.labels[t] % 20),
        lw=0.8,
        zorder=2,
        label=f"top {cfg.n_t} per cluster",
    )
    v3 = cr.vector.reshape(-1, 3)
    ax.scatter(
        v3[:, 1],
        v3[:, 2],
        marker="s",
        s=30,
        c=[cmap(i % 20) for i in range(len(v3))],
        edgecolors="k",
        lw=0.6,
        zorder=3,
        label=f"cluster means (C_k={cfg.c_k})",
    )
    for i, (p, x, y) in enumerate(v3[:5]):
        ax.annotate(f"{i + 1}: {p:.1f} dB", (x, y), xytext=(4, 4), textcoords="offset points", fontsize=7)
    ax.plot(
        est.x_m,
        est.y_m,
        marker="*",
        ms=18,
        color="red",
        mec="k",
        ls="none",
        zorder=5,
        label=f"estimate ({est.method}{', ' + est.model if est.model else ''})",
    )
    tx, ty = est.extras.get("truth_x_m"), est.extras.get("truth_y_m")
    if tx is not None:
        ax.plot(tx, ty, marker="X", ms=13, color="white", mec="k", ls="none", zorder=5, label="truth")
        ax.plot([tx, est.x_m], [ty, est.y_m], "r:", lw=1.2, zorder=4)
        ax.annotate(
            f"{est.error_m:.1f} m",
            ((tx + est.x_m) / 2, (ty + est.y_m) / 2),
            color="red",
            xytext=(8, -14),
            textcoords="offset points",
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    name = Path(str(log.path)).name if log.path else "flight"
    ax.set_title(
        title
        or f"{name}: estimate {est.x_m:.1f}, {est.y_m:.1f} m"
        + (f", error {est.error_m:.1f} m" if est.error_m is not None else ""),
        fontsize=10,
    )
    ax.legend(loc="best", fontsize=7, framealpha=0.85)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
