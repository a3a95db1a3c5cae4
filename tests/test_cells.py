"""``mission.cells``: binning samples by an integer key and averaging per bin, the one home of cell
averaging."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.cells import altitude_index, bin_index, bin_means, cell_average, cell_keys
from mission.samples import FlightSamples


@settings(max_examples=20, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1), n=st.integers(1, 120), cell=st.sampled_from([0.7, 5.0, 12.5])
)
def test_bin_means_are_the_per_key_means(seed, n, cell):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-40.0, 40.0, (n, 2))
    v = rng.normal(-60.0, 8.0, n)
    keys = cell_keys(xy, cell)
    inv, cnt = bin_index(keys)
    mx, mv = bin_means(inv, cnt, xy[:, 0], v)
    distinct = np.unique(keys, axis=0)
    assert cnt.sum() == n and len(cnt) == len(distinct) and np.all(cnt > 0)
    # bins in sorted key order, each the mean of exactly its samples
    for b, k in enumerate(distinct):
        mine = np.all(keys == k, axis=1)
        assert np.array_equal(inv == b, mine)
        assert np.isclose(mx[b], xy[mine, 0].mean()) and np.isclose(mv[b], v[mine].mean())
        assert np.all(np.floor(xy[mine] / cell) == k)


def test_cell_average_two_altitudes_and_yaw_on_the_circle():
    # two samples per cell at 30 m, one cell flown again at 50 m; yaw either side of north
    enu = np.array(
        [[1.0, 1.0, 30.0], [3.0, 2.0, 30.2], [1.0, 1.0, 50.0], [12.0, 1.0, 30.0], [13.0, 2.0, 29.8]]
    )
    att = np.zeros((5, 3))
    att[:, 2] = np.radians([350.0, 10.0, 90.0, 0.0, 0.0])
    f = FlightSamples(
        enu_m=enu, rss_dbm=np.array([-50.0, -54.0, -70.0, -60.0, -62.0]), attitude_rad=att
    )
    c = cell_average(f, 5.0)
    assert len(c) == 3 and c.n_columns == 2 and c.area_m2 == 50.0
    assert np.allclose(c.enu_m[0], [2.0, 1.5, 30.1]) and c.rss_dbm[0] == -52.0 and c.count[0] == 2
    assert abs(np.degrees(c.yaw_rad[0])) < 1e-9  # 350 and 10 deg average to north, not 180
    assert np.array_equal(altitude_index(enu[:, 2]), [0, 0, 1, 0, 0])
