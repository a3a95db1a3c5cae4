"""``geo.square_grid``: the one builder of candidate grids (localizers, preview coverage, adaptive
planner)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.geo import square_grid


@settings(max_examples=40, deadline=None)
@given(
    x0=st.floats(-300, 300),
    y0=st.floats(-300, 300),
    w=st.floats(0, 200),
    h=st.floats(0, 200),
    step=st.floats(0.5, 20.0),
)
def test_square_grid_covers_the_box_at_its_step(x0, y0, w, h, step):
    g = square_grid((x0, y0, x0 + w, y0 + h), step)
    ny, nx, two = g.shape
    assert two == 2 and nx == len(np.arange(x0, x0 + w + 1e-9, step)) and ny >= 1
    assert np.array_equal(g[0, 0], [x0, y0])  # from the corner; rows along y, columns along x
    assert np.allclose(np.diff(g[..., 0], axis=1), step) and np.allclose(
        np.diff(g[..., 1], axis=0), step
    )
    # reaches the far edge
    assert g[..., 0].max() <= x0 + w + 1e-9 and x0 + w - g[..., 0].max() < step
    c = square_grid((x0, y0, x0 + w, y0 + h), step, centred=True)
    if c.size:
        assert np.array_equal(c[0, 0], [x0 + step / 2, y0 + step / 2])
        assert c[..., 0].max() < x0 + w and c[..., 1].max() < y0 + h  # cell centres inside the box


def test_far_edge_included_when_on_the_grid():
    g = square_grid((0.0, 0.0, 30.0, 20.0), 10.0)
    assert g.shape == (3, 4, 2) and np.array_equal(g[-1, -1], [30.0, 20.0])
    assert square_grid((0.0, 0.0, 30.0, 20.0), 10.0, centred=True).shape == (2, 3, 2)
