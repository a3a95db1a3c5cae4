"""Offset-invariant robust residuals: one home for the free RSS offset and the soft-L1 / Huber / L2
losses.

Why: a real receiver's dB carry an unknown constant offset (SPEC section 5), so every comparison of
a model with measured RSS removes a constant fitted on the very samples being scored, and real
flights have deep fades, so the fit uses a robust loss.  The localizer's grid search
(``mission.localize.classical``), the gap diagnosis (``mission.gap.fit``) and the calibration all
need the same two things, written once here:

- ``robust_offset``: the offset of residuals under a robust loss: the median as a start, then one
  Huber IRLS step with weights ``w = min(1, f / |r - median|)`` (closed form, vectorised over
  leading axes);
- ``rho`` / ``per_sample_loss``: ``f^2 rho(r / f)`` with ``rho(z) = z^2`` (l2),
  ``2 (sqrt(1 + z^2) - 1)`` (soft_l1, the ``scipy.optimize.least_squares`` definition) or
  ``z^2 if |z| <= 1 else 2 |z| - 1`` (huber); all three are ~ r^2 for |r| << f;
- ``huber_lstsq``: a linear fit under the Huber loss (IRLS with the same weights), for the few
  rows of which one may be far off (the budget's pace per leg: one slow leg is not a pace).
"""

from __future__ import annotations

import numpy as np

from mission.errors import InputError

LOSSES = ("l2", "soft_l1", "huber")


def rho(z: np.ndarray, loss: str) -> np.ndarray:
    """Dimensionless loss of the scaled residual ``z = r / f`` (``LOSSES``); unknown names raise
    InputError."""
    z = np.asarray(z, dtype=float)
    if loss == "l2":
        return z * z
    if loss == "soft_l1":
        return 2.0 * (np.sqrt(1.0 + z * z) - 1.0)
    if loss == "huber":
        a = np.abs(z)
        return np.where(a <= 1.0, z * z, 2.0 * a - 1.0)
    raise InputError(f"unknown loss {loss!r} (expected {', '.join(LOSSES)})", field="loss")


def per_sample_loss(r: np.ndarray, loss: str = "l2", f_scale: float = 6.0) -> np.ndarray:
    """``f^2 rho(r / f)`` in dB^2 (equals r^2 for l2 whatever ``f_scale``)."""
    if loss == "l2":
        r = np.asarray(r, dtype=float)
        return r * r
    return f_scale * f_scale * rho(np.asarray(r, dtype=float) / f_scale, loss)


def robust_offset(resid: np.ndarray, f_scale: float = 6.0, axis: int = -1) -> np.ndarray:
    """Offset of ``resid`` along ``axis``: median, then one Huber IRLS step (weights min(1, f / |r -
    med|))."""
    resid = np.asarray(resid, dtype=float)
    off = (
        median_1d(resid)
        if resid.ndim == 1 and resid.size
        else np.median(resid, axis=axis, keepdims=True)
    )
    z = resid - off
    w = huber_weights(z, f_scale)
    off = off + np.sum(w * z, axis=axis, keepdims=True) / np.sum(w, axis=axis, keepdims=True)
    return np.squeeze(off, axis=axis)


def huber_weights(z: np.ndarray, f_scale: float) -> np.ndarray:
    """IRLS weights of the Huber step about the median: min(1, f / |z|) (``robust_offset``, and the
    gap's offsets of several flights at once)."""
    return np.minimum(1.0, f_scale / np.maximum(np.abs(z), 1e-12))


def huber_lstsq(A: np.ndarray, y: np.ndarray, f_scale: float, iters: int = 100) -> np.ndarray:
    """Coefficients ``x`` minimising the Huber loss of ``y - A x`` (scale ``f_scale``), by IRLS
    from the least-squares fit.  Why: residuals past ``f_scale`` count linearly, so one row far
    off no longer drags the fit; with ``f_scale`` at the data's noise it is a least-absolute-
    deviations fit (the median's regression), exact data stay exact."""
    A, y = np.asarray(A, dtype=float), np.asarray(y, dtype=float)
    x = np.linalg.lstsq(A, y, rcond=None)[0]
    for _ in range(iters):
        w = np.sqrt(huber_weights(y - A @ x, f_scale))
        x_new = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)[0]
        if np.allclose(x_new, x, rtol=0.0, atol=1e-9):
            return x_new
        x = x_new
    return x


def median_1d(r: np.ndarray) -> np.ndarray:
    """``np.median(r, keepdims=True)`` of a non-empty 1-D array, bit for bit (the same partition and
    mean of the middle pair; NaN if any), without its generic-axis overhead: the fits call it ~100
    000 times."""
    h = r.size // 2
    part = np.partition(r, [h - 1, h, -1] if r.size % 2 == 0 else [h, -1])
    if np.isnan(part[-1]):
        return np.full(1, np.nan)
    return np.array([(part[h - 1] + part[h]) / 2.0 if r.size % 2 == 0 else part[h]])


def robust_cost(
    resid: np.ndarray, loss: str = "soft_l1", f_scale: float = 6.0
) -> tuple[np.ndarray, np.ndarray]:
    """Offset and mean robust cost along the last axis of ``resid`` (e.g. (K candidates, N samples)
    -> (K,)).

    The offset is ``robust_offset`` for every loss (the grid search's convention); the cost is the
    mean of ``per_sample_loss`` of the offset-removed residuals.
    """
    resid = np.asarray(resid, dtype=float)
    off = robust_offset(resid, f_scale, axis=-1)
    z = (resid - off[..., None]) / f_scale
    return off, f_scale**2 * rho(z, loss).mean(axis=-1)


def offset_residual(
    meas: np.ndarray, pred: np.ndarray, slope: bool = False, loss: str = "l2", f_scale: float = 6.0
) -> np.ndarray:
    """``meas - (c + s pred)`` with the free constants fitted: the offset ``c`` is the mean (l2) or
    ``robust_offset`` (soft_l1, huber); with ``slope`` also a path-gain slope ``s`` (least
    squares)."""
    meas = np.asarray(meas, dtype=float)
    pred = np.asarray(pred, dtype=float)
    if meas.size == 0:
        return meas.copy()
    if slope and meas.size > 2 and np.std(pred) > 1e-9:
        s, c = np.polyfit(pred, meas, 1)
        return meas - (c + s * pred)
    r = meas - pred
    if loss == "l2":
        return r - np.mean(r)
    if loss not in LOSSES:
        rho(np.zeros(1), loss)  # raises the InputError naming the loss
    return r - robust_offset(r, f_scale)
