"""Localizer input features, one implementation for training and inference alike (paper section
"DL-Based Model For RF Localization with UAV", SPEC sections 4-5).

Pipeline of ``cluster_features(x, y, rss, cfg)`` on the raw per-sample arrays of one flight:

1. **Grouping** (``grouping``): mean of consecutive non-overlapping groups of ``n_g`` samples, of
   the dB values and of the positions alike (the paper averages dB, not linear power).  A trailing
   incomplete group is dropped.
2. **Gaussian smoothing** (``gaussian_smooth``): discrete convolution with a Gaussian kernel of
   ``sigma`` samples, length ``6 sigma + 1`` (``kernel_sigmas * sigma + 1``), normalised to sum 1.
   At the ends the signal is extended with its edge value (``mode="nearest"``), so a constant stays
   constant and the first/last samples are not pulled towards 0 dB as zero-padding would.
3. **3D clustering**: k-means (scikit-learn, ``random_state=cfg.seed``, ``algorithm="lloyd"``,
   ``n_init=cfg.n_init``) on the standardised (z-scored per column) points (x, y, smoothed RSS).
   The paper says "KNN"; a clustering needs k-means (SPEC section 4).
4. Per cluster, the ``n_t`` samples with the highest smoothed RSS (all of them when a cluster has
   fewer than ``n_t``); their mean smoothed RSS ``p_c`` and mean coordinates ``x_c, y_c``.
5. **Offset invariance** (SPEC section 5): with ``offset_invariant=True`` the reference level
   ``max(smoothed RSS)`` of the flight is subtracted from every ``p_c`` (and the clustering sees the
   RSS z-scored), so the features are relative dB and identical for ``rss + c``.
6. **Cluster order** (``order="rss_desc"``): clusters are sorted by ``p_c`` descending, ties broken
   by ``x_c`` then ``y_c`` ascending.  The order therefore depends only on the cluster contents,
   never on k-means' label numbering.

Output: ``[p_1, x_1, y_1, ..., p_Ck, x_Ck, y_Ck]`` (length ``3 C_k``), float64.  Coordinates are
local ENU metres about the *field origin* of whoever computed them
(``mission.geo.afar_field().origin`` for the AFAR field); a model's metadata carries the origin it
was trained with, and inference converts the log's positions into that frame before calling these
functions.

Speed: k-means per flight is unavoidable.  Measured on a real AFAR flight (about 10 000 grouped
points, 20 clusters, 2 CPU cores): ``KMeans(lloyd, n_init=1)`` about 20-40 ms, ``n_init=3`` about
2.5x that, ``elkan`` and ``MiniBatchKMeans`` were not faster at this size; hence the default
``n_init=1`` with k-means++ seeding (deterministic with the fixed seed).  ``cluster_features_batch``
vectorises grouping and smoothing over flights and runs one k-means per flight.  k-means runs with
one OpenMP thread (``mission.threads``, ``$RFSL_THREADS``): on a busy 2-core machine its default
threads spin against each other (0.38 s instead of 0.02 s per flight; same labels).

``arc_step_m`` > 0 (off by default, the paper has no such step) first resamples a flight to one
point per ``arc_step_m`` metres of path (``resample_by_arc``), so creeping or hovering does not
weight a spot by the time spent there.

The paper's baseline input ``normalised_rss(rss, cfg)``: grouped RSS, minus its maximum (offset
removed), divided by ``rss_scale_db``, linearly resampled to ``rss_length`` values.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np
from scipy.ndimage import convolve1d, gaussian_filter1d
from threadpoolctl import ThreadpoolController

from mission.cells import bin_index, bin_means
from mission.errors import InputError
from mission.fields import Fields
from mission.threads import thread_limits

FEATURE_VERSION = 1
# keys added after version 1, with the value that reproduces the features of models/datasets written
# before
LATER_KEYS = {"arc_step_m": 0.0}


@dataclass(frozen=True)
class FeatureConfig:
    """All settings that define the features; travels in the ONNX metadata as a JSON dict."""

    n_g: int = 2  # grouping factor N_g
    sigma: float = 20.0  # Gaussian smoothing sigma, in grouped samples
    kernel_sigmas: int = 6  # kernel length = kernel_sigmas * sigma + 1
    c_k: int = 20  # number of clusters C_k
    n_t: int = 40  # top samples per cluster
    order: str = "rss_desc"  # cluster order rule (only "rss_desc" exists)
    offset_invariant: bool = True  # subtract max(smoothed RSS) from the cluster RSS values
    seed: int = 0  # k-means random_state
    n_init: int = 1  # k-means restarts
    rss_length: int = (
        10000  # normalised-RSS baseline: resampled length (S / N_g for a 10 min flight)
    )
    rss_scale_db: float = 20.0  # normalised-RSS baseline: dB per unit
    arc_step_m: float = (
        0.0  # > 0: resample the flight to one point per arc_step_m of path first (0: off)
    )
    version: int = FEATURE_VERSION

    def __post_init__(self) -> None:
        """Refuse a configuration the features cannot be computed with (``mission.fields``: one
        line naming ``feature_config.<key>``)."""
        f = Fields(self.to_dict(), None, "feature_config")
        for k in ("n_g", "c_k", "n_t", "n_init"):
            f.int_(k, lo=1)
        f.num("sigma", lo=0.0)
        f.num("arc_step_m", lo=0.0)
        f.str_("order", choices=("rss_desc",))  # the cluster order rule

    @property
    def kernel_length(self) -> int:
        return int(round(self.kernel_sigmas * self.sigma)) + 1

    @property
    def n_features(self) -> int:
        return 3 * self.c_k

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> FeatureConfig:
        """Build from a dict; unknown keys are refused (InputError naming the key); keys added after
        a model or dataset was written take their defaults, which reproduce the features it was made
        with."""
        Fields(d, None, "feature_config").done(f.name for f in fields(cls))
        return cls(**d)

    @staticmethod
    def normalised(d: dict) -> dict:
        """``d`` with the later keys (``LATER_KEYS``) filled in where absent: compare configurations
        through this."""
        return {**LATER_KEYS, **d}

    def mismatch(self, other: FeatureConfig | dict) -> str | None:
        """The first key whose value differs from ``other`` (None when identical); a dict ``other``
        written before a later key existed counts as having that key's neutral value."""
        o = other.to_dict() if isinstance(other, FeatureConfig) else FeatureConfig.normalised(other)
        mine = self.to_dict()
        for k in sorted(set(mine) | set(o)):
            if k not in o or k not in mine or mine[k] != o[k]:
                return k
        return None


def gaussian_kernel(sigma: float, kernel_sigmas: int = 6) -> np.ndarray:
    """Normalised Gaussian kernel of length ``kernel_sigmas * sigma + 1`` (``[1.0]`` for sigma
    0)."""
    half = int(round(kernel_sigmas * sigma)) // 2
    if sigma <= 0 or half == 0:
        return np.ones(1)
    mu = np.arange(-half, half + 1, dtype=float)
    g = np.exp(-0.5 * (mu / sigma) ** 2)
    return g / g.sum()


def grouping(values: np.ndarray, n_g: int) -> np.ndarray:
    """Mean of consecutive non-overlapping groups of ``n_g`` along the last axis (remainder
    dropped).

    Works on (N,), (M, N) arrays of dB values, and on (N, 2)/(N, 3) positions via ``axis`` moved
    first: for positions call ``grouping(pos.T, n_g).T``.
    """
    v = np.asarray(values, dtype=float)
    n = v.shape[-1] // n_g
    if n_g == 1:
        return v.copy()
    return v[..., : n * n_g].reshape(*v.shape[:-1], n, n_g).mean(axis=-1)


def gaussian_smooth(values: np.ndarray, sigma: float, kernel_sigmas: int = 6) -> np.ndarray:
    """Convolve along the last axis with the normalised Gaussian kernel (edges: nearest value)."""
    v = np.asarray(values, dtype=float)
    k = gaussian_kernel(sigma, kernel_sigmas)
    if k.size == 1:
        return v.copy()
    return convolve1d(v, k, axis=-1, mode="nearest")


def resample_by_arc(
    x: np.ndarray, y: np.ndarray, rss: np.ndarray, step_m: float, smooth_samples: float = 15.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One point per ``step_m`` of flown path: the mean x, y and RSS of the samples in each
    arc-length bin.

    Why: grouping and smoothing count samples, so a vehicle that creeps or hovers (AFAR team 288
    moved at about 1 m/s median and hovered at points) puts many more samples on a spot than the
    simulator's 5 m/s cruise, and k-means weights spots by their sample count.  After resampling,
    one path metre carries the same weight at any speed; a hover collapses to one averaged point.
    Arc length is measured on positions smoothed over ``smooth_samples`` samples, so GPS jitter
    while hovering does not add path.
    """
    if step_m <= 0 or x.size < 2:
        return x, y, rss

    sx = gaussian_filter1d(x, smooth_samples, mode="nearest")
    sy = gaussian_filter1d(y, smooth_samples, mode="nearest")
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(sx), np.diff(sy)))])
    inv, cnt = bin_index(np.floor(s / step_m).astype(np.int64))
    return tuple(bin_means(inv, cnt, x, y, rss))  # type: ignore[return-value]


def preprocess(
    x: np.ndarray, y: np.ndarray, rss: np.ndarray, cfg: FeatureConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Arc resampling,) grouping, then smoothing: grouped x, grouped y and smoothed grouped RSS (1D
    arrays of one flight)."""
    x, y, rss = (np.asarray(a, dtype=float).ravel() for a in (x, y, rss))
    if not (x.size == y.size == rss.size):
        raise InputError(f"x, y and rss differ in length ({x.size}, {y.size}, {rss.size})")
    if not (np.isfinite(x).all() and np.isfinite(y).all() and np.isfinite(rss).all()):
        raise InputError("NaN or inf in positions or RSS given to the features")
    x, y, rss = resample_by_arc(x, y, rss, cfg.arc_step_m)
    gx, gy, gp = grouping(x, cfg.n_g), grouping(y, cfg.n_g), grouping(rss, cfg.n_g)
    return gx, gy, gaussian_smooth(gp, cfg.sigma, cfg.kernel_sigmas)


@dataclass
class ClusterResult:
    """Everything the clustering produced for one flight (the vector plus what a plot needs)."""

    vector: np.ndarray  # (3 C_k,) features in the documented order
    x: np.ndarray  # grouped x (M,)
    y: np.ndarray  # grouped y (M,)
    p: np.ndarray  # smoothed grouped RSS (M,), as given (not offset-corrected)
    labels: np.ndarray  # (M,) cluster rank 0..C_k-1 in the output order (0 = strongest cluster)
    top: np.ndarray  # (M,) bool, sample is among its cluster's top n_t
    reference_db: float  # level subtracted from p_c (0 when offset_invariant is False)


def _standardise(a: np.ndarray) -> np.ndarray:
    s = a.std(axis=0)
    return (a - a.mean(axis=0)) / np.where(s > 0, s, 1.0)


# the threadpoolctl controller for k-means, made once (making one scans libraries: ms)
_KMEANS_LIMIT: list = []


def _kmeans_labels(pts: np.ndarray, cfg: FeatureConfig) -> np.ndarray:
    # lazy on purpose (noqa): scikit-learn takes 1-2 s to import (scipy.stats), paid only by the
    # clustering features; it loads its OpenMP runtime before the controller looks for it
    from sklearn.cluster import KMeans  # noqa: PLC0415

    km = KMeans(n_clusters=cfg.c_k, n_init=cfg.n_init, random_state=cfg.seed, algorithm="lloyd")
    if not _KMEANS_LIMIT:
        _KMEANS_LIMIT.append(ThreadpoolController())
    with thread_limits(controller=_KMEANS_LIMIT[0], user_api="openmp"):
        return km.fit_predict(pts)


def summarise_clusters(
    gx: np.ndarray, gy: np.ndarray, gp: np.ndarray, labels: np.ndarray, cfg: FeatureConfig
) -> ClusterResult:
    """Top-n_t means per cluster, offset removal and deterministic ordering (vectorised, no
    per-sample loop).

    ``labels`` may use any numbering (0..C_k-1); the result does not depend on it.
    """
    k = cfg.c_k
    labels = np.asarray(labels, dtype=np.int64)
    order = np.lexsort((-gp, labels))  # by label, then RSS descending
    sl = labels[order]
    starts = np.searchsorted(sl, np.arange(k))
    rank = np.arange(sl.size) - starts[sl]
    top_sorted = rank < cfg.n_t
    top = np.zeros(gp.size, dtype=bool)
    top[order[top_sorted]] = True
    cnt = np.bincount(labels[top], minlength=k).astype(float)
    if np.any(cnt == 0):
        raise InputError(
            f"k-means left an empty cluster ({int((cnt == 0).sum())} of {k}); too few samples?"
        )
    pc = np.bincount(labels[top], weights=gp[top], minlength=k) / cnt
    xc = np.bincount(labels[top], weights=gx[top], minlength=k) / cnt
    yc = np.bincount(labels[top], weights=gy[top], minlength=k) / cnt
    ref = float(gp.max()) if cfg.offset_invariant else 0.0
    pc = pc - ref
    rank_of = np.lexsort((yc, xc, -pc))  # output order: p desc, then x, then y
    inv = np.empty(k, dtype=np.int64)
    inv[rank_of] = np.arange(k)
    vec = np.stack([pc[rank_of], xc[rank_of], yc[rank_of]], axis=1).ravel()
    return ClusterResult(vec, gx, gy, gp, inv[labels], top, ref)


def cluster_details(
    x: np.ndarray, y: np.ndarray, rss: np.ndarray, cfg: FeatureConfig | None = None
) -> ClusterResult:
    """Full clustering result of one flight from raw per-sample x, y (ENU m) and RSS (dB)."""
    cfg = cfg or FeatureConfig()
    gx, gy, gp = preprocess(x, y, rss, cfg)
    if gp.size < cfg.c_k:
        raise InputError(f"only {gp.size} grouped samples, fewer than the {cfg.c_k} clusters")
    rel = gp - gp.max() if cfg.offset_invariant else gp
    labels = _kmeans_labels(_standardise(np.stack([gx, gy, rel], axis=1)), cfg)
    return summarise_clusters(gx, gy, gp, labels, cfg)


def cluster_features(
    x: np.ndarray, y: np.ndarray, rss: np.ndarray, cfg: FeatureConfig | None = None
) -> np.ndarray:
    """The 3D-clustering feature vector ``(3 C_k,)`` of one flight (see the module docstring)."""
    return cluster_details(x, y, rss, cfg).vector


def cluster_features_batch(
    xy: np.ndarray, rss: np.ndarray, cfg: FeatureConfig | None = None
) -> np.ndarray:
    """Features of M flights: ``xy`` (N, 2) shared by all flights or (M, N, 2); ``rss`` (M, N) ->
    (M, 3 C_k).

    Grouping and smoothing are vectorised over flights; k-means runs once per flight.
    """
    cfg = cfg or FeatureConfig()
    rss = np.atleast_2d(np.asarray(rss, dtype=float))
    xy = np.asarray(xy, dtype=float)
    m, n = rss.shape
    if xy.shape not in ((n, 2), (m, n, 2)):
        raise InputError(f"xy must be ({n}, 2) or ({m}, {n}, 2), got {xy.shape}")
    if cfg.arc_step_m > 0:  # resampled lengths differ per flight: one flight at a time
        xys = np.broadcast_to(xy, (m, n, 2))
        return np.stack(
            [cluster_features(xys[i, :, 0], xys[i, :, 1], rss[i], cfg) for i in range(m)]
        )
    if not np.isfinite(rss).all() or not np.isfinite(xy).all():
        raise InputError("NaN or inf in the dataset positions or RSS")
    gp = gaussian_smooth(grouping(rss, cfg.n_g), cfg.sigma, cfg.kernel_sigmas)
    gxy = grouping(np.moveaxis(xy, -1, -2), cfg.n_g)  # (..., 2, G)
    if gp.shape[1] < cfg.c_k:
        raise InputError(f"only {gp.shape[1]} grouped samples, fewer than the {cfg.c_k} clusters")
    rel = gp - gp.max(axis=1, keepdims=True) if cfg.offset_invariant else gp
    out = np.empty((m, cfg.n_features))
    shared = xy.ndim == 2
    if shared:
        gx, gy = gxy[0], gxy[1]
        sxy = _standardise(np.stack([gx, gy], axis=1))
    for i in range(m):  # one k-means per flight
        if not shared:
            gx, gy = gxy[i, 0], gxy[i, 1]
            sxy = _standardise(np.stack([gx, gy], axis=1))
        r = rel[i]
        sd = r.std()
        pts = np.column_stack([sxy, (r - r.mean()) / (sd if sd > 0 else 1.0)])
        labels = _kmeans_labels(pts, cfg)
        out[i] = summarise_clusters(gx, gy, gp[i], labels, cfg).vector
    return out


def normalised_rss(rss: np.ndarray, cfg: FeatureConfig | None = None) -> np.ndarray:
    """The paper's baseline input: grouped RSS minus its max, over ``rss_scale_db``, resampled to
    ``rss_length`` (linear interpolation over the sample index).  (N,) -> (L,) or (M, N) -> (M,
    L)."""
    cfg = cfg or FeatureConfig()
    r = np.asarray(rss, dtype=float)
    if not np.isfinite(r).all():
        raise InputError("NaN or inf in the RSS given to the normalised-RSS features")
    g = grouping(r, cfg.n_g)
    g = (g - g.max(axis=-1, keepdims=True)) / cfg.rss_scale_db
    n = g.shape[-1]
    if n < 2:
        raise InputError("too few samples for the normalised-RSS features")
    src = np.linspace(0.0, 1.0, n)
    dst = np.linspace(0.0, 1.0, cfg.rss_length)
    if g.ndim == 1:
        return np.interp(dst, src, g)
    # vectorised linear interpolation over all rows
    pos = dst * (n - 1)
    i0 = np.clip(np.floor(pos).astype(int), 0, n - 2)
    w = pos - i0
    return g[..., i0] * (1 - w) + g[..., i0 + 1] * w
