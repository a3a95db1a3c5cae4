"""Preview: summary numbers, the expected-error map with the model-based estimator, the PNG and its
size."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _figures import assert_png_drawn, capture_figures, legend_labels

from mission.cli.main import main
from mission.preview import area_grid, coverage, expected_error_map, ml_grid_estimator
from mission.simulate import fly_path
from mission.spec import load_mission

MISSIONS = Path(__file__).resolve().parents[1] / "missions"


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


class _FreeSpace:
    """Free-space path loss with isotropic antennas (used where mission.physics is not
    importable)."""

    def rss_dbm(self, tx, rx, attitude=None):
        d = (
            np.linalg.norm(np.asarray(tx)[..., None, :] - np.asarray(rx), axis=-1)
            if np.asarray(tx).ndim == 1
            else np.linalg.norm(np.asarray(tx) - np.asarray(rx), axis=-1)
        )
        lam = 299792458.0 / 3.32e9
        return 41.0 + 20 * np.log10(lam / (4 * np.pi * np.maximum(d, 1.0)))


def _model(spec):
    try:
        return spec.propagation_model()
    except ImportError:
        return _FreeSpace()


def test_coverage_of_default_spiral():
    spec = load_mission()
    cov = coverage(spec.field.rover_area, spec.waypoints_enu())
    # the south quadrants lie in the overlap the spiral covers; the north ones reach beyond the
    # flight area
    assert cov.quadrant_max_m["SE"] < 15 and cov.quadrant_max_m["SW"] < 30
    assert cov.max_m == pytest.approx(max(cov.quadrant_max_m.values()))


def test_estimator_is_offset_invariant_and_finds_the_source():
    spec = load_mission(MISSIONS / "waypoints.yaml")
    model = _model(spec)

    _, pos, att, _ = fly_path(spec.flight_path_enu(), spec.sim_config(), np.random.default_rng(0))
    pos, att = pos[::10], att[::10]
    est = ml_grid_estimator(model, spec.field.rover_area, 1.5, pos, att, step_m=4.0)
    tx = np.array([[60.0, 180.0, 1.5], [200.0, 240.0, 1.5]])
    rss = np.asarray(model.rss_dbm(tx[:, None, :], pos, att), dtype=float)
    a = est(pos, att, rss)
    b = est(pos, att, rss + 17.0)  # an uncalibrated receiver
    assert np.array_equal(a, b)
    assert np.all(np.linalg.norm(a - tx[:, :2], axis=1) < 4.0)
    # reference written out: per record, the cell centre minimising sum((r - mean r - (p - mean
    # p))^2)
    noisy = rss + np.random.default_rng(5).normal(0.0, 3.0, rss.shape)
    cand = area_grid(spec.field.rover_area, 4.0)
    pred = np.asarray(
        model.rss_dbm(np.column_stack([cand, np.full(len(cand), 1.5)])[:, None, :], pos, att),
        dtype=float,
    )
    pred_c = pred - pred.mean(axis=1, keepdims=True)
    for r, got in zip(noisy, est(pos, att, noisy), strict=True):
        sse = np.sum((pred_c - (r - r.mean())) ** 2, axis=1)
        assert np.array_equal(got, cand[np.argmin(sse)])


def test_expected_error_map_and_custom_estimator():
    spec = load_mission(MISSIONS / "waypoints.yaml")
    model = _model(spec)
    em = expected_error_map(spec, 4, np.random.default_rng(1), model=model)
    assert em.error_m.shape == (4, 4) and np.all(np.isfinite(em.error_m))
    assert em.median_m < 20
    calls = []

    def centre(pos, att, rss):  # a trivial plug-in localizer: always the rover-area centre
        calls.append(rss.shape)
        return np.tile([116.5, 237.9], (len(rss), 1))

    em2 = expected_error_map(spec, 4, np.random.default_rng(1), estimator=centre, model=model)
    assert len(calls) == 4 and em2.mean_m > em.mean_m


def test_preview_png_has_expected_size(tmp_path, capsys):
    out = tmp_path / "p.png"
    with capture_figures() as figs:
        assert (
            main(["preview", str(MISSIONS / "spiral.yaml"), "--out", str(out), "--size", "800x600"])
            == 0
        )
    assert _png_size(out) == (800, 600)
    assert_png_drawn(out, size=(800, 600))
    (fig,) = figs
    ax, cbar = fig.axes  # the map and the flight-time colour bar
    assert cbar.get_ylabel() == "flight time (min)"
    assert legend_labels(ax)[:2] == ["flight area (UAV)", "rover area (transmitter)"]
    assert "waypoints" in legend_labels(ax) and "home (take-off)" in legend_labels(ax)
    text = capsys.readouterr().out
    assert "RSS samples" in text and "worst point" in text


def test_preview_accuracy_png(tmp_path):
    pytest.importorskip("mission.physics")
    out = tmp_path / "a.png"
    with capture_figures() as figs:
        assert (
            main(
                [
                    "preview",
                    str(MISSIONS / "waypoints.yaml"),
                    "--out",
                    str(out),
                    "--accuracy",
                    "--grid",
                    "4",
                    "--seed",
                    "3",
                ]
            )
            == 0
        )
    assert _png_size(out) == (1200, 1000)
    assert_png_drawn(out, size=(1200, 1000))
    (fig,) = figs
    ax, cbar = fig.axes  # the map with the error heatmap, and its colour bar
    (heat,) = ax.images
    assert heat.get_array().shape == (4, 4) and "expected localization error" in cbar.get_ylabel()
    assert "expected error: mean" in ax.get_title() and "simulated path" in legend_labels(ax)


def test_preview_bad_arguments(tmp_path, capsys):
    assert main(["preview", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "x.png")]) == 2
    assert "none.yaml" in capsys.readouterr().err
    assert main(["preview", str(MISSIONS / "spiral.yaml"), "--size", "big"]) == 2
