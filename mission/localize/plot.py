"""Plot a localization: the flight coloured by smoothed RSS, the 3D clusters and their top-n_t
samples, the estimate and (when known) the truth.  matplotlib with the Agg backend (no display
needed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mission.files import save_figure
from mission.geo import afar_field
from mission.localize import Estimate
from mission.localize.api import search_area
from mission.localize.features import FeatureConfig, cluster_details
from mission.localize.region import Region


def field_areas(log) -> list:
    """The areas to draw for a log, in its frame: the AFAR flight and rover areas when the log
    shares the AFAR origin, else the sidecar's rover area (if any).  Why: a path or estimate means
    little without the field."""
    af = afar_field()
    o = log.origin
    off = af.origin.to_enu(o.lat_deg, o.lon_deg, o.alt_m)
    if float(np.hypot(off[0], off[1])) < 1.0:
        return [af.flight_area, af.rover_area]
    ra = search_area(log)
    return [ra] if ra is not None else []


def draw_areas(ax, areas) -> None:
    """Outline areas (flight area solid blue, rover area dashed green, as in ``rfsl preview``)."""
    for a in areas:
        rover = "rover" in a.name
        v = np.vstack([a.vertices, a.vertices[:1]])
        ax.plot(
            v[:, 0],
            v[:, 1],
            "--" if rover else "-",
            color="#2ca02c" if rover else "#1f77b4",
            lw=1.2,
            label=a.name,
            zorder=0,
        )


def robust_limits(values, lo_pct: float = 2.0, hi_pct: float = 99.5) -> tuple[float, float]:
    """Colour-scale limits at robust percentiles: deep nulls and take-off outliers must not wash out
    a map."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(v, [lo_pct, hi_pct])
    return (float(lo), float(hi)) if hi > lo else (float(lo) - 0.5, float(hi) + 0.5)


def power_unit(log) -> str:
    """'dBm' for simulated (calibrated) RSS, 'dB' for a real receiver's uncalibrated values."""
    src = log.meta.get("rss_source") if isinstance(log.meta, dict) else None
    return "dBm" if isinstance(src, dict) and src.get("kind") == "sim" else "dB"


def draw_regions(ax, regions: Sequence[Region]) -> None:
    """Outline the estimate's uncertainty regions (``Region``), one style per level."""
    styles = {0.5: ("-", 1.6), 0.9: ("--", 1.2)}
    for reg in regions:
        ls, lw = styles.get(round(reg.level, 2), (":", 1.0))
        for k, poly in enumerate(reg.polygons):
            a = np.asarray(poly)
            ax.plot(
                a[:, 0],
                a[:, 1],
                color="crimson",
                ls=ls,
                lw=lw,
                zorder=4,
                label=f"{100 * reg.level:.0f} % region" if k == 0 else None,
            )


def draw_candidates(ax, cands: list, top: int = 6) -> None:
    """Mark the evidence stage's candidates (the ``top`` heaviest), the marker's size by weight,
    labelled with their source; a network outside its training domain is drawn hollow."""
    for k, c in enumerate(cands[:top]):
        w = c.weight or 0.0
        ax.plot(
            c.x_m,
            c.y_m,
            marker="o",
            ms=5 + 10 * np.sqrt(w),
            ls="none",
            zorder=4,
            mfc="orange" if c.in_domain else "none",
            mec="k",
            mew=0.8,
            label="candidates (size: weight)" if k == 0 else None,
        )
        ax.annotate(
            f"{c.source} {w:.2f}",
            (c.x_m, c.y_m),
            xytext=(5, -9),
            textcoords="offset points",
            fontsize=6,
        )


def plot_localization(
    log,
    est: Estimate,
    out: str | Path,
    cfg: FeatureConfig | None = None,
    area=None,
    title: str | None = None,
) -> Path:
    """Draw ``log`` (its cruise part, positions in the log's frame) with ``est``; writes ``out``
    (PNG)."""
    # matplotlib stays lazy (noqa): the Agg backend is chosen before pyplot loads, and runs
    # without a plot do not pay its import
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    cfg = cfg or FeatureConfig()
    enu = log.enu()
    cr = cluster_details(enu[:, 0], enu[:, 1], log["rss_dbm"], cfg)
    fig, ax = plt.subplots(figsize=(8.5, 7.5), dpi=120)
    areas = field_areas(log)
    if area is not None and not any(a.name == area.name for a in areas):
        areas.append(area)
    draw_areas(ax, areas)
    draw_clusters(fig, ax, cr, cfg, plt.get_cmap("tab20"))
    draw_estimate(ax, est)
    label_axes(ax, log.label, est, title)
    ax.legend(loc="best", fontsize=7, framealpha=0.85)
    ax.grid(alpha=0.3)
    fig.tight_layout()

    try:
        out = save_figure(fig, out, "--plot")  # whole or not at all; an OS error is one line
    finally:
        plt.close(fig)
    return out


def draw_clusters(fig, ax, cr, cfg: FeatureConfig, cmap) -> None:
    """The smoothed RSS (relative to its maximum) with its colour bar, each cluster's top samples
    and the cluster means the network reads."""
    rel = cr.p - cr.p.max()
    vmin, vmax = robust_limits(rel)
    sc = ax.scatter(cr.x, cr.y, c=rel, s=3, cmap="viridis", vmin=vmin, vmax=vmax, zorder=1)
    fig.colorbar(sc, ax=ax, label="smoothed RSS relative to max (dB), 2-99.5 % range", shrink=0.8)
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
    # cluster means are relative to the strongest: dB, not dBm
    for i, (p, x, y) in enumerate(v3[:5]):
        ax.annotate(
            f"{i + 1}: {p:.1f} dB", (x, y), xytext=(4, 4), textcoords="offset points", fontsize=7
        )


def draw_estimate(ax, est: Estimate) -> None:
    """The estimate, its regions and candidates, and the truth with the error line when known."""
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
    draw_regions(ax, est.regions)
    draw_candidates(ax, est.candidates)
    tx, ty = est.extras.get("truth_x_m"), est.extras.get("truth_y_m")
    if tx is not None:
        ax.plot(
            tx, ty, marker="X", ms=13, color="white", mec="k", ls="none", zorder=5, label="truth"
        )
        ax.plot([tx, est.x_m], [ty, est.y_m], "r:", lw=1.2, zorder=4)
        ax.annotate(
            f"{est.error_m:.1f} m",
            ((tx + est.x_m) / 2, (ty + est.y_m) / 2),
            color="red",
            xytext=(8, -14),
            textcoords="offset points",
        )


def label_axes(ax, name: str, est: Estimate, title: str | None) -> None:
    """Equal aspect, axis labels and the title (the estimate and its error, or ``title``)."""
    ax.set_aspect("equal")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_title(
        title
        or f"{name}: estimate {est.x_m:.1f}, {est.y_m:.1f} m"
        + (f", error {est.error_m:.1f} m" if est.error_m is not None else ""),
        fontsize=10,
    )
