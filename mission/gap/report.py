"""Rendering a ``Diagnosis``: rich tables in the terminal, PNG plots and a JSON of every figure.

Why JSON of every figure: plots are for people, the numbers behind them are for regression checks
and for re-plotting; every PNG written here has a same-named entry in ``gap.json`` holding exactly
what was drawn.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mission import jsonsafe
from mission.files import save_figure, write_text
from mission.gap.align import SEGMENTS
from mission.gap.diagnose import Diagnosis, rung_table
from mission.gap.fit import RANKING_RULE, _pooled
from mission.gap.stats import ecdf
from mission.gap.structure import name_missing
from mission.gap.text import details_text, summary_paragraph

PAPER_P90_DB = (
    22.0  # "over 90 % of the errors contained within 22 dB" (enhanced two-ray, paper Fig. Abserror)
)


# --------------------------------------------------------------------------------------------
# figures


def figures(d: Diagnosis) -> dict[str, Any]:
    """The data of every figure (also the JSON)."""
    figs: dict[str, Any] = {}
    figs["cdf_models"] = {
        g.name: {
            "abs_error_db": g.cdf_x.tolist(),
            "cdf": g.cdf_q.tolist(),
            "pooled": g.pooled,
            "per_flight": g.per_flight,
        }
        for g in d.gaps
    }
    figs["cdf_ladder"] = {}
    for r in d.rungs:
        x, q = ecdf(_pooled(r.residuals))
        figs["cdf_ladder"][r.label] = {"abs_error_db": x.tolist(), "cdf": q.tolist()}
    figs["breakdown"] = [b.as_dict() for b in d.breakdown]
    fm = d.field_map
    figs["field_map"] = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in fm.items()}
    for k in ("mean_db",):
        figs["field_map"][k] = [
            [None if not np.isfinite(v) else float(v) for v in row] for row in fm[k]
        ]
    figs["field_map"]["transmitters"] = [f.tx_enu_m.tolist() for f in d.flights]
    polar = {}
    for r in (d.rungs[0], d.rungs[-1]):
        al = d.alignments
        az = np.concatenate([np.rad2deg(a.az_b) for a in al])
        res = np.concatenate(r.residuals)
        ok = np.isfinite(res)
        edges = np.arange(0.0, 361.0, 15.0)
        g = np.digitize(az[ok], edges) - 1
        cnt = np.bincount(g, minlength=24)[:24]
        m = np.bincount(g, weights=res[ok], minlength=24)[:24] / np.maximum(cnt, 1)
        polar[r.label] = {
            "body_azimuth_deg": (0.5 * (edges[:-1] + edges[1:])).tolist(),
            "mean_db": m.tolist(),
            "count": cnt.tolist(),
        }
    figs["polar_body_azimuth"] = polar
    figs["ladder"] = rung_table(d)
    figs["rankings"] = {
        r.label: [
            {
                "name": x.name,
                "rms_before_db": x.rms_before,
                "rms_after_db": x.rms_after,
                "p90_after_db": x.p90_after,
                "loss_reduction_db2": x.loss_reduction,
                "rel_reduction": x.rel_reduction,
                "ci_lo_db2": x.ci_lo,
                "significant": x.significant,
                "block_len": x.block_len,
                "params_fold_mean": x.params_mean(),
                "params_per_fold": x.fold_params,
            }
            for x in r.ranking
        ]
        for r in d.rungs
    }
    figs["localization"] = d.localization
    figs["freeform_shapes"] = freeform_shapes(d)
    figs["structure"] = d.structure
    return figs


SCHEMA_VERSION = 2
# shapes go to figures["freeform_shapes"], not into the summary
_BIG = (
    "shape",
    "resemblances",
    "time_shapes",
)


def _small(p: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in p.items() if k not in _BIG}


def _ladder_summary(d: Diagnosis) -> list[dict[str, Any]]:
    """``summary``'s ``ladder``: per rung, what was added, its parameters, the held-out figures and
    the footprint."""
    ladder = []
    for row in rung_table(d):
        s = row["pooled"]
        ladder.append(
            {
                "rung": row["rung"],
                "added": row["added"],
                "params": _small(row["params"]),
                "heldout": {
                    "n": s["n"],
                    "median_abs_db": s["median_abs_db"],
                    "p90_abs_db": s["p90_abs_db"],
                    "rms_db": s["rms_db"],
                },
                "footprint": d.footprints.get(row["rung"]),
            }
        )
    return ladder


def _rankings_summary(d: Diagnosis) -> dict[str, list[dict[str, Any]]]:
    """``summary``'s ``rankings``: per rung, the candidates tried on top of it in rank order."""
    return {
        r.label: [
            {
                "name": x.name,
                "tier": x.tier,
                "loss_reduction_db2": x.loss_reduction,
                "rel_reduction": x.rel_reduction,
                "ci_lo_db2": x.ci_lo,
                "significant": x.significant,
                "rms_after_db": x.rms_after,
                "p90_after_db": x.p90_after,
                "params": _small(x.params_mean()),
            }
            for x in r.ranking
        ]
        for r in d.rungs
        if r.ranking
    }


_STRUCTURE_KEYS = ("verdict", "rule", "residual_std_db", "test")
_VARIOGRAM_KEYS = (
    "sigma_db",
    "sigma_ci_db",
    "corr_len",
    "corr_len_ci",
    "unit",
    "nugget_db",
    "nugget_ci_db",
    "correlated_fraction",
)


def _structure_summary(d: Diagnosis) -> dict[str, Any]:
    """``summary``'s ``structure``: the verdict and the variograms (along the path, over space) of
    the base and final rungs' residuals."""
    return {
        k: {kk: vv for kk, vv in v.items() if kk in _STRUCTURE_KEYS}
        | {
            kk: {q: v[kk][q] for q in _VARIOGRAM_KEYS}
            for kk in ("along_path", "spatial")
            if kk in v
        }
        for k, v in d.structure.items()
    }


def summary(d: Diagnosis) -> dict[str, Any]:
    """The stable machine-readable result (top of ``gap.json``; ``rfsl gap --json`` prints it).

    ``ladder``: one entry per rung: ``rung`` (label), ``added`` (effect or null), ``params``
    (fitted, fold mean), ``heldout`` (median/p90/rms |error| dB, n), ``footprint`` (size_db where it
    acts, where). ``rankings``: rung label -> candidates tried on top of it, in rank order:
    ``name``, ``tier``, ``loss_reduction_db2``, ``rel_reduction``, ``ci_lo_db2`` (one-sided lower
    bound), ``significant``, ``rms_after_db``, ``p90_after_db``, ``params``.  ``named``: what the
    diagnosis names as missing first; ``structure``: residual variograms and verdict of the base and
    final rungs; ``rule``: the ranking rule.
    """
    first = d.rungs[0].ranking
    return {
        "schema": SCHEMA_VERSION,
        "named": name_missing(first, d.structure.get("base")),
        "text": summary_paragraph(d),
        "rule": RANKING_RULE,
        "ladder": _ladder_summary(d),
        "rankings": _rankings_summary(d),
        "structure": _structure_summary(d),
        "near_nadir": d.near_nadir,
        "time_power": d.time_power,
        "frames": d.frames,
        "config": d.config,
        "flights": [{"name": f.name, "n": len(f)} for f in d.flights],
    }


def freeform_shapes(d: Diagnosis) -> dict[str, Any]:
    """The fitted shape of every free-form candidate on the first rung (fold 0) and of any added
    one."""
    out = {}
    for r in d.rungs:
        for x in r.ranking:
            if x.tier == "free-form" and (r is d.rungs[0] or x.name in {q.added for q in d.rungs}):
                p = x.fold_params[0]
                # time_drift: its per-flight curves are in its params (``time_shapes``)
                if not p.get("shape"):
                    continue
                out.setdefault(
                    x.name,
                    {
                        "rung": r.label,
                        "size_db": p.get("size_db"),
                        "resembles": p.get("resembles"),
                        "resemblance_corr": p.get("resemblance_corr"),
                        "where": p.get("where"),
                        "resemblances": p.get("resemblances"),
                        "shape": p.get("shape"),
                    },
                )
    return out


def _plot_cdfs(plt: Any, figs: dict[str, Any], path: Path) -> None:
    """The reference models' and the ladder rungs' |error| CDFs side by side."""
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    for name, g in figs["cdf_models"].items():
        ax[0].plot(
            g["abs_error_db"], g["cdf"], label=f"{name} (p90 {g['pooled']['p90_abs_db']:.1f} dB)"
        )
    ax[0].axvline(PAPER_P90_DB, color="k", ls=":", lw=1, label="paper: 90 % within 22 dB")
    ax[0].axhline(0.9, color="grey", ls=":", lw=0.8)
    ax[0].set(
        xlabel="|measured - model| (dB, offset fitted)",
        ylabel="CDF",
        title="Reference models (all samples)",
    )
    ax[0].legend(fontsize=8)
    for name, g in figs["cdf_ladder"].items():
        ax[1].plot(
            g["abs_error_db"], g["cdf"], label=name if len(name) < 60 else "..." + name[-57:]
        )
    ax[1].axhline(0.9, color="grey", ls=":", lw=0.8)
    ax[1].set(xlabel="|error| (dB), held-out", ylabel="CDF", title="Ladder rungs (held-out)")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def _plot_breakdown(plt: Any, d: Diagnosis, path: Path) -> None:
    """The base residual's mean per bin of every variable, flagged bins in red."""
    n = len(d.breakdown)
    fig, axs = plt.subplots(2, (n + 1) // 2, figsize=(4 * ((n + 1) // 2), 7))
    for ax, b in zip(np.ravel(axs), d.breakdown, strict=False):
        x = np.arange(len(b.mean)) if b.variable == "segment" else b.centers
        yerr = np.vstack([b.mean - b.lo, b.hi - b.mean])
        ax.errorbar(x, b.mean, yerr=np.nan_to_num(yerr), fmt="o", color="C0", ms=4, capsize=2)
        if b.flagged.any():
            ax.plot(
                np.asarray(x)[b.flagged], b.mean[b.flagged], "o", color="C3", ms=7, label="flagged"
            )
            ax.legend(fontsize=7)
        ax.axhline(0, color="k", lw=0.8)
        if b.variable == "segment":
            ax.set_xticks(range(len(SEGMENTS)), SEGMENTS)
        ax.set(title=b.variable, ylabel="mean residual dB")
    fig.suptitle(f"Residual of '{d.base_label}' (measured - model), 95 % block-bootstrap CI")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _plot_field_map(plt: Any, d: Diagnosis, path: Path) -> None:
    """The base residual over the field, significant cells marked, tracks and transmitters."""
    fm = d.field_map
    fig, ax = plt.subplots(figsize=(7, 6))
    ext = [
        fm["x0"],
        fm["x0"] + fm["nx"] * fm["cell_m"],
        fm["y0"],
        fm["y0"] + fm["ny"] * fm["cell_m"],
    ]
    lim = np.nanmax(np.abs(fm["mean_db"])) if np.isfinite(fm["mean_db"]).any() else 1.0
    im = ax.imshow(fm["mean_db"], origin="lower", extent=ext, cmap="RdBu_r", vmin=-lim, vmax=lim)
    yy, xx = np.nonzero(fm["flagged"])
    ax.plot(
        fm["x0"] + (xx + 0.5) * fm["cell_m"],
        fm["y0"] + (yy + 0.5) * fm["cell_m"],
        "k.",
        ms=3,
        label="significant cell",
    )
    for f in d.flights:
        ax.plot(f.enu_m[:, 0], f.enu_m[:, 1], lw=0.3, color="grey", alpha=0.6)
        ax.plot(*f.tx_enu_m[:2], "k*", ms=12)
    fig.colorbar(im, label="mean residual dB (measured - model)")
    ax.set(
        xlabel="east m",
        ylabel="north m",
        title=f"Residual of '{d.base_label}' over the field (* = transmitter)",
    )
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _plot_polar(plt: Any, figs: dict[str, Any], path: Path) -> None:
    """The mean residual over body azimuth, per rung."""
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)
    for name, p in figs["polar_body_azimuth"].items():
        th = np.deg2rad(np.append(p["body_azimuth_deg"], p["body_azimuth_deg"][0]))
        ax.plot(
            th,
            np.append(p["mean_db"], p["mean_db"][0]),
            label=name if len(name) < 50 else "..." + name[-47:],
        )
    ax.set_title("Mean residual (dB) over body azimuth (0 = nose, clockwise)")
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.1, -0.15))
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _plot_localization(plt: Any, d: Diagnosis, path: Path) -> None:
    """The grid search's error per flight on every rung."""
    fig, ax = plt.subplots(figsize=(8, 4))
    labels = [r["rung"].split(" + ")[-1] for r in d.localization]
    for f in d.flights:
        ax.plot(
            range(len(labels)),
            [r["errors_m"][f.name] for r in d.localization],
            "o-",
            label=f.name,
            ms=4,
        )
    ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right")
    ax.set(
        ylabel="grid-search error m",
        title="Localization cost per rung (model-based grid search)",
    )
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _plot_freeform(plt: Any, shapes: dict[str, Any], path: Path) -> None:
    """Every free-form shape: a gain map over two angles, or a loss over distance and height."""
    fig, axs = plt.subplots(1, len(shapes), figsize=(5.5 * len(shapes), 4.2), squeeze=False)
    for ax, (name, sh) in zip(axs[0], shapes.items(), strict=True):
        g = sh["shape"]
        if "gain_db" in g:
            im = ax.pcolormesh(
                g["azimuth_deg"],
                g["elevation_deg"],
                np.array(g["gain_db"]),
                cmap="RdBu_r",
                shading="auto",
            )
            fig.colorbar(im, ax=ax, label="dB")
            ax.set(
                xlabel="body azimuth deg" if name == "rx_gain_map" else "compass azimuth deg",
                ylabel="body depression deg" if name == "rx_gain_map" else "elevation deg",
            )
        else:
            ax.plot(g["distance_m"], g["loss_vs_distance_db"], label="vs distance (m)")
            ax2 = ax.twiny()
            ax2.plot(g["height_m"], g["loss_vs_height_db"], "C1", label="vs height (m)")
            ax.set(xscale="log", xlabel="distance m", ylabel="dB")
            ax2.set_xlabel("UAV height m (orange)")
        ax.set_title(
            f"{name}: {sh['size_db']:.1f} dB, like {sh['resembles']} "
            f"({sh['resemblance_corr']:.2f})",
            fontsize=9,
        )
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def write_report(d: Diagnosis, out_dir: str | Path) -> list[Path]:
    """PNGs (CDFs, ladder CDFs, breakdown, residual map, polar) and ``gap.json``; returns the
    paths."""
    # matplotlib stays lazy (noqa): the Agg backend is chosen before pyplot loads, and runs
    # without a plot do not pay its import
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figs = figures(d)
    plots = [
        ("cdf.png", lambda p: _plot_cdfs(plt, figs, p)),
        ("breakdown.png", lambda p: _plot_breakdown(plt, d, p)),
        ("field_map.png", lambda p: _plot_field_map(plt, d, p)),
        ("polar_body_azimuth.png", lambda p: _plot_polar(plt, figs, p)),
    ]
    if d.localization:
        plots.append(("localization.png", lambda p: _plot_localization(plt, d, p)))
    if figs["freeform_shapes"]:
        plots.append(("freeform.png", lambda p: _plot_freeform(plt, figs["freeform_shapes"], p)))
    paths = []
    for name, plot in plots:
        paths.append(out / name)
        plot(paths[-1])

    paths.append(out / "details.txt")
    write_text(paths[-1], details_text(d))
    doc = {
        **summary(d),
        "block_lens": d.block_lens,
        "flights": [
            {"name": f.name, "n": len(f), "tx_enu": f.tx_enu_m.tolist()} for f in d.flights
        ],
        "figures": figs,
    }
    paths.append(out / "gap.json")
    write_text(paths[-1], jsonsafe.dumps(doc, indent=1))
    return paths
