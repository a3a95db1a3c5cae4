"""mission.robust: the one home of the free RSS offset and the robust losses (closed forms and
limits)."""

from __future__ import annotations

import numpy as np
import pytest

from mission.errors import InputError
from mission.robust import (
    huber_lstsq,
    offset_residual,
    per_sample_loss,
    rho,
    robust_cost,
    robust_offset,
)


def test_losses_closed_forms_and_small_residual_limit() -> None:
    z = np.array([0.0, 0.5, 1.0, 3.0])
    assert np.allclose(rho(z, "l2"), z * z)
    assert np.allclose(rho(z, "soft_l1"), 2 * (np.sqrt(1 + z * z) - 1))
    assert np.allclose(rho(z, "huber"), [0.0, 0.25, 1.0, 5.0])
    small = np.array([1e-3, -2e-3])
    for loss in ("soft_l1", "huber"):  # all ~ r^2 for |r| << f
        assert np.allclose(per_sample_loss(small, loss, 6.0), small**2, rtol=1e-5)
    assert np.allclose(per_sample_loss(np.array([3.0]), "l2", 0.1), 9.0)
    with pytest.raises(InputError):
        rho(z, "cauchy")


def test_robust_offset_ignores_a_deep_fade_and_l2_is_the_mean() -> None:
    rng = np.random.default_rng(0)
    r = 17.0 + rng.normal(0, 1.0, 2000)
    r[:200] -= 40.0  # 10 % deep fades
    assert abs(robust_offset(r, 6.0) - 17.0) < 1.0  # one Huber step: fades keep weight f / 40 dB
    assert abs(np.mean(r) - 17.0) > 3.5
    assert abs(np.mean(offset_residual(r, np.zeros_like(r), loss="l2"))) < 1e-9
    assert abs(np.median(offset_residual(r, np.zeros_like(r), loss="soft_l1"))) < 1.0
    # slope: meas = 3 + 2 pred exactly
    pred = np.linspace(-80, -40, 50)
    assert np.allclose(offset_residual(3 + 2 * pred, pred, slope=True), 0.0, atol=1e-9)


def test_robust_cost_vectorised_over_candidates() -> None:
    """(K, N) residuals: row k is shifted by k dB, so offsets step by 1 and the costs are equal."""
    rng = np.random.default_rng(1)
    base = rng.normal(0, 2.0, 500)
    R = base[None, :] + np.arange(4.0)[:, None]
    off, cost = robust_cost(R, "soft_l1", 6.0)
    assert np.allclose(np.diff(off), 1.0) and np.allclose(cost, cost[0])
    off1, cost1 = robust_cost(base, "soft_l1", 6.0)
    assert off1 == pytest.approx(off[0]) and cost1 == pytest.approx(cost[0])


def test_huber_lstsq_is_exact_on_exact_data_ignores_one_far_row_and_is_lstsq_at_a_large_scale():
    rng = np.random.default_rng(0)
    A = np.column_stack([rng.uniform(1, 50, 12), np.ones(12)])
    x = np.array([1.2, 3.0])
    y = A @ x
    np.testing.assert_allclose(huber_lstsq(A, y, 0.1), x, atol=1e-8)
    y_far = y.copy()
    y_far[4] += 20.0
    np.testing.assert_allclose(huber_lstsq(A, y_far, 0.1), x, atol=0.01)  # to about the scale
    l2 = np.linalg.lstsq(A, y_far, rcond=None)[0]
    assert np.abs(l2 - x).max() > 0.5  # what the far row does to least squares
    np.testing.assert_allclose(huber_lstsq(A, y_far, 1e6), l2, atol=1e-9)
