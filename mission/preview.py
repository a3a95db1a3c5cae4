"""Mission preview: summary numbers, an expected-localization-error map, and a map-like PNG.

The expected error comes by default from ``ml_grid_estimator``: the localizer's model grid search
(``mission.localize.classical.ModelGridSearch``) in its many-records form (``FixedGeometrySearch``)
with the same propagation model that simulated the RSS, on a ``step_m`` grid of cell centres over
the rover area. With Gaussian dB noise and an unknown constant receiver offset (SPEC section 5) the
likelihood is maximised by the candidate whose predicted RSS, after removing its mean, is closest in
least squares to the measured RSS after removing its mean; so the estimate is offset-invariant.  It
is an optimistic bound (the model is exact apart from noise and attitude perturbation; the product's
default for real logs is ``fusion``); plug another localizer in through ``expected_error_map(...,
estimator=...)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mission.files import save_figure
from mission.geo import Area, square_grid
from mission.localize.classical import ModelGridSearch
from mission.simulate import fly_path
from mission.trajectory.checks import check_mission

# estimator(positions (N, 3), attitude (N, 3) rad, rss (T, N) dB) -> (T, 2) estimated x, y What the
# default expected-error map assumes, said wherever its numbers are shown (table and plot title).
ESTIMATOR_NOTE = (
    "assuming an ML grid search with the mission's own {model} physics (an optimistic bound)"
)
Estimator = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclass
class Coverage:
    """How close the flight path comes to the rover area (horizontal distances, metres)."""

    max_m: float  # worst point of the rover area: its distance to the path
    mean_m: float
    quadrant_max_m: dict[str, float]  # NW, NE, SW, SE quarter of the rover area's bounding box


def _dist_to_polyline(pts: np.ndarray, path: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Horizontal distance from points (P, 2) to the polyline ``path`` (K, >=2)."""
    a, b = path[:-1, :2], path[1:, :2]
    ab = b - a
    den = np.maximum(np.sum(ab * ab, axis=1), 1e-12)
    out = np.empty(len(pts))
    for s in range(0, len(pts), chunk):
        p = pts[s : s + chunk, None, :]
        t = np.clip(np.sum((p - a) * ab, axis=-1) / den, 0.0, 1.0)
        out[s : s + chunk] = np.min(np.linalg.norm(p - (a + t[..., None] * ab), axis=-1), axis=-1)
    return out


def area_grid(area: Area, step_m: float) -> np.ndarray:
    """Points (P, 2) of a square grid with spacing ``step_m`` inside ``area`` (cell centres)."""
    g = square_grid(area.bounds, step_m, centred=True).reshape(-1, 2)
    return g[area.contains(g)]


def coverage(area: Area, path: np.ndarray, step_m: float = 2.0) -> Coverage:
    """Closest approach of ``path`` to every part of ``area`` (max, mean and per quadrant)."""
    g = area_grid(area, step_m)
    d = _dist_to_polyline(g, path)
    x0, y0, x1, y1 = area.bounds
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    quads = {
        "NW": (g[:, 0] < cx) & (g[:, 1] >= cy),
        "NE": (g[:, 0] >= cx) & (g[:, 1] >= cy),
        "SW": (g[:, 0] < cx) & (g[:, 1] < cy),
        "SE": (g[:, 0] >= cx) & (g[:, 1] < cy),
    }
    return Coverage(
        float(d.max()),
        float(d.mean()),
        {k: float(d[m].max()) if m.any() else float("nan") for k, m in quads.items()},
    )


@dataclass
class Summary:
    """Numbers of a mission preview."""

    length_m: float
    duration_s: float
    time_budget_s: float
    n_samples: int
    n_waypoints: int
    coverage: Coverage
    min_fence_clearance_m: float
    violations: list[str]


def summarize(spec) -> Summary:
    """Length, duration, RSS samples, fence clearance and rover-area coverage of a mission."""
    rep = check_mission(spec)
    cov = coverage(spec.field.rover_area, spec.waypoints_enu())
    return Summary(
        rep.length_m,
        rep.duration_s,
        rep.time_budget_s,
        rep.n_samples,
        rep.n_waypoints,
        cov,
        rep.min_fence_clearance_m,
        [v.message for v in rep.violations],
    )


def ml_grid_estimator(
    model,
    area: Area,
    tx_height_m: float,
    positions: np.ndarray,
    attitude: np.ndarray,
    step_m: float = 4.0,
) -> Estimator:
    """The default ``Estimator`` (module docstring): ``ModelGridSearch(model).fixed_geometry`` along
    the flown ``positions`` / ``attitude`` with the cell centres of a ``step_m`` grid over ``area``
    as candidates."""
    search = ModelGridSearch(model, tx_height_m=tx_height_m, area=area, step_m=step_m)
    fixed = search.fixed_geometry(positions, attitude, area_grid(area, step_m))

    def estimate(positions: np.ndarray, attitude: np.ndarray, rss: np.ndarray) -> np.ndarray:
        return fixed.predict_xy(rss)  # the geometry is the one the predictions were computed for

    return estimate


@dataclass
class ErrorMap:
    """Expected localization error (m) on a grid of transmitter positions over the rover area."""

    x: np.ndarray  # (G,) cell centres east
    y: np.ndarray  # (H,) cell centres north
    error_m: np.ndarray  # (H, G); NaN outside the rover area
    estimates: np.ndarray  # (H, G, 2)

    @property
    def mean_m(self) -> float:
        return float(np.nanmean(self.error_m))

    @property
    def median_m(self) -> float:
        return float(np.nanmedian(self.error_m))


def expected_error_map(
    spec,
    grid: int,
    rng: np.random.Generator,
    estimator: Estimator | None = None,
    model=None,
    subsample: int = 10,
    progress: Callable[[int, int], None] | None = None,
) -> ErrorMap:
    """Simulate the mission for a ``grid`` x ``grid`` lattice of transmitters over the rover area
    and
    localize each with ``estimator`` (default: ``ml_grid_estimator`` with the mission's own model).

    One kinematic flight is flown (attitude perturbation from ``rng``) and every ``subsample``-th
    RSS sample is kept, as a localizer would average them anyway; each transmitter gets its own
    noise draw. ``progress(done, total)`` is called after each row of the lattice.
    """
    model = model if model is not None else spec.propagation_model()
    cfg = spec.sim_config()
    _, pos, att, _ = fly_path(spec.flight_path_enu(), cfg, rng)
    pos, att = pos[::subsample], att[::subsample]
    area = spec.field.rover_area
    if estimator is None:
        estimator = ml_grid_estimator(model, area, spec.source.tx_height_m, pos, att)
    x0, y0, x1, y1 = area.bounds
    xs = x0 + (np.arange(grid) + 0.5) * (x1 - x0) / grid
    ys = y0 + (np.arange(grid) + 0.5) * (y1 - y0) / grid
    err = np.full((grid, grid), np.nan)
    est = np.full((grid, grid, 2), np.nan)
    for j, y in enumerate(ys):
        pts = np.column_stack([xs, np.full(grid, y)])
        inside = area.contains(pts)
        if inside.any():
            tx = np.column_stack([pts[inside], np.full(int(inside.sum()), spec.source.tx_height_m)])
            rss = np.asarray(model.rss_dbm(tx[:, None, :], pos, att), dtype=float)
            rss = rss + rng.normal(0.0, cfg.noise_db, size=rss.shape)
            e = np.asarray(estimator(pos, att, rss), dtype=float).reshape(-1, 2)
            est[j, inside] = e
            err[j, inside] = np.linalg.norm(e - pts[inside], axis=1)
        if progress:
            progress(j + 1, grid)
    return ErrorMap(xs, ys, err, est)


def render_preview(
    spec,
    out,
    *,
    error_map: ErrorMap | None = None,
    summary: Summary | None = None,
    rng: np.random.Generator | None = None,
    size_px: tuple[int, int] = (1200, 1000),
    dpi: int = 100,
):
    """Draw the areas, waypoints, simulated flown path, budget and (optionally) the error
    heatmap."""
    # matplotlib stays lazy (noqa): the Agg backend is chosen before pyplot loads, and runs
    # without a plot do not pay its import
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    summary = summary or summarize(spec)
    rng = rng if rng is not None else np.random.default_rng(spec.source.seed)
    t, pos, _, _ = fly_path(spec.flight_path_enu(), spec.sim_config(), rng)
    wps = spec.waypoints_enu()

    fig, ax = plt.subplots(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
    draw_areas(ax, spec.field.flight_area, spec.field.rover_area)
    if error_map is not None:
        draw_error_map(fig, ax, error_map)
    draw_flight(fig, ax, spec, t, pos, wps, over_heatmap=error_map is not None)
    draw_summary(ax, spec, summary, error_map)
    set_frame(ax, spec, wps)
    fig.tight_layout()

    try:
        save_figure(fig, out, "--out", dpi=dpi)
    finally:
        plt.close(fig)
    return out


def draw_areas(ax, fa, ra) -> None:
    """The flight area (UAV) and the rover area (transmitter) as outlined polygons."""
    # lazy like render_preview's pyplot (noqa): matplotlib loads only when a preview is drawn
    from matplotlib.patches import Polygon  # noqa: PLC0415

    ax.add_patch(
        Polygon(
            fa.vertices,
            closed=True,
            fc=(0.12, 0.47, 0.71, 0.10),
            ec="#1f77b4",
            lw=2.5,
            label="flight area (UAV)",
            zorder=2,
        )
    )
    ax.add_patch(
        Polygon(
            ra.vertices,
            closed=True,
            fc=(0.17, 0.63, 0.17, 0.10),
            ec="#2ca02c",
            lw=2.5,
            ls="--",
            label="rover area (transmitter)",
            zorder=2,
        )
    )


def draw_error_map(fig, ax, em: ErrorMap) -> None:
    """The expected-error heatmap with its colour bar (clipped at the 98th percentile)."""
    dx, dy = (
        np.diff(em.x[:2]) if len(em.x) > 1 else [1.0],
        np.diff(em.y[:2]) if len(em.y) > 1 else [1.0],
    )
    ext = (em.x[0] - dx[0] / 2, em.x[-1] + dx[0] / 2, em.y[0] - dy[0] / 2, em.y[-1] + dy[0] / 2)
    im = ax.imshow(
        em.error_m,
        origin="lower",
        extent=ext,
        cmap="magma_r",
        alpha=0.85,
        interpolation="nearest",
        zorder=1,
    )
    cb = fig.colorbar(im, ax=ax, fraction=0.04, pad=0.02)
    lo, hi = np.nanpercentile(em.error_m, [0, 98]) if np.isfinite(em.error_m).any() else (0.0, 1.0)
    im.set_clim(lo, max(hi, lo + 1e-6))  # one failed cell must not wash out the scale
    cb.set_label("expected localization error (m), clipped at the 98th percentile")


def draw_flight(fig, ax, spec, t, pos, wps, *, over_heatmap: bool) -> None:
    """The simulated path (coloured by time, or plain over a heatmap), waypoints, home and the
    transmitter when fixed."""
    if not over_heatmap:
        sc = ax.scatter(pos[::5, 0], pos[::5, 1], c=t[::5] / 60.0, s=2, cmap="viridis", zorder=3)
        fig.colorbar(sc, ax=ax, fraction=0.04, pad=0.02).set_label("flight time (min)")
    else:  # one colour scale only: the path in plain cyan over the heatmap
        ax.plot(pos[:, 0], pos[:, 1], color="white", lw=3.5, zorder=3)
        ax.plot(pos[:, 0], pos[:, 1], color="#17becf", lw=1.6, zorder=3, label="simulated path")
    ax.plot(wps[:, 0], wps[:, 1], "o", ms=5, mfc="white", mec="black", zorder=4, label="waypoints")
    for i in (0, len(wps) - 1) if len(wps) > 30 else range(len(wps)):
        ax.annotate(
            str(i), wps[i, :2], xytext=(4, 4), textcoords="offset points", fontsize=8, zorder=5
        )
    home = spec.home_enu
    ax.plot(
        home[0],
        home[1],
        marker="^",
        ms=11,
        color="#d62728",
        mec="black",
        ls="none",
        zorder=5,
        label="home (take-off)",
    )
    if not isinstance(spec.source.tx, str):
        ax.plot(
            spec.source.tx[0],
            spec.source.tx[1],
            marker="*",
            ms=16,
            color="gold",
            mec="black",
            ls="none",
            zorder=6,
            label="transmitter",
        )


def draw_summary(ax, spec, summary: Summary, error_map: ErrorMap | None) -> None:
    """The title (length, duration against the budget, samples, expected error) and the coverage
    box."""
    used = summary.duration_s / summary.time_budget_s
    title = (
        f"{spec.name}: {spec.trajectory.generator} at {spec.altitude_m:g} m, "
        f"{summary.length_m / 1000:.2f} km, {summary.duration_s / 60:.1f} of "
        f"{summary.time_budget_s / 60:.1f} min ({used:.0%} of budget), {summary.n_samples} RSS "
        "samples"
    )
    if error_map is not None:
        title += (
            f"\nexpected error: mean {error_map.mean_m:.1f} m, median {error_map.median_m:.1f} m, "
            + ESTIMATOR_NOTE.format(model=spec.source.model)
        )
    ax.set_title(title, fontsize=11, color="black" if used <= 1 else "#d62728")
    text = [
        f"worst rover-area point {summary.coverage.max_m:.0f} m from the path",
        "per quadrant: "
        + ", ".join(f"{k} {v:.0f}" for k, v in summary.coverage.quadrant_max_m.items()),
        f"fence clearance >= {summary.min_fence_clearance_m:.1f} m (margin "
        f"{spec.fence_margin_m:g} m)",
    ]
    if summary.violations:
        text.append("NOT FLYABLE: " + summary.violations[0])
    ax.text(
        0.01,
        0.01,
        "\n".join(text),
        transform=ax.transAxes,
        fontsize=9,
        va="bottom",
        zorder=7,
        bbox={"boxstyle": "round", "fc": "white", "alpha": 0.85, "ec": "0.7"},
    )


def set_frame(ax, spec, wps) -> None:
    """Limits around the areas, waypoints and home; equal aspect, labels, grid and legend."""
    fa, ra, home = spec.field.flight_area, spec.field.rover_area, spec.home_enu
    allv = np.vstack([fa.vertices, ra.vertices, wps[:, :2], home[None, :2]])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    pad = 0.05 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=9, framealpha=0.9)
