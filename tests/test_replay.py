"""``rfsl replay``: summary numbers and the RSS-coloured path of a small synthetic log."""

from __future__ import annotations

import numpy as np
from _figures import assert_png_drawn, capture_figures, legend_labels

from mission.cli.main import main
from mission.flightlog import make_meta, read_flight_log, write_flight_log
from mission.geo import Origin
from mission.replay import plot, summary


def _log(tmp_path):
    o = Origin(35.727, -78.696, 100.0)
    t = np.arange(0, 10, 0.1)
    enu = np.stack([t * 5, np.zeros_like(t), np.full_like(t, 30.0)], -1)
    lat, lon, alt = o.to_geodetic(enu)
    cols = {
        "t_s": t,
        "lat_deg": lat,
        "lon_deg": lon,
        "alt_m": alt,
        "rel_alt_m": enu[:, 2],
        "roll_deg": np.sin(t),
        "pitch_deg": -3 + np.cos(t),
        "yaw_deg": np.full_like(t, 90.0),
        "rss_dbm": -60 + t,
    }
    p = tmp_path / "f.csv"
    write_flight_log(p, cols, make_meta(o, {"kind": "sim"}, {"x_m": 20.0, "y_m": 5.0, "z_m": 1.5}))
    return p


def test_summary_and_plot(tmp_path):
    log = read_flight_log(_log(tmp_path))
    s = summary(log)
    assert s["samples"] == 100 and abs(s["rate_hz"] - 10) < 1e-6
    assert abs(s["path_length_m"] - 49.5) < 0.1 and s["rss_max_db"] == -50.1
    with capture_figures() as figs:
        png = plot(log, tmp_path / "f.png")
    # 7 x 6 in at 120 dpi, coloured path on a white background
    assert_png_drawn(png, size=(840, 720))
    (fig,) = figs
    ax, cbar = fig.axes  # the map and its RSS colour bar
    assert "RSS" in cbar.get_ylabel()
    (path,) = ax.collections[-1:]  # every sample drawn, coloured by its RSS
    assert np.allclose(path.get_offsets(), log.enu()[:, :2]) and np.allclose(
        path.get_array(), log["rss_dbm"]
    )
    assert legend_labels(ax) == ["strongest RSS", "true transmitter"]
    star = [ln for ln in ax.lines if ln.get_label() == "strongest RSS"][0]
    # RSS rises with t
    assert (star.get_xdata()[0], star.get_ydata()[0]) == (
        log.enu()[-1, 0],
        log.enu()[-1, 1],
    )


def test_cli(tmp_path, capsys):
    p = _log(tmp_path)
    assert main(["replay", str(p), "--out", str(tmp_path / "x.png")]) == 0
    assert "duration_s" in capsys.readouterr().out
    assert main(["replay", str(tmp_path / "missing.csv")]) == 2
