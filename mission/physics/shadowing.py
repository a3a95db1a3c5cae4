"""Spatially correlated log-normal shadowing: covariance models, field sampling and variogram
fitting.

Why one module: the simulator draws shadowing for training data, the gap diagnosis draws it for its
self-test, krigs it, and measures it on real residuals; all must mean the same thing by "sigma" and
"correlation length".  Two covariance families are named here (``COVARIANCES``):

- ``gaussian``:    C(h) = sigma^2 exp(-h^2 / L^2)  (smooth; 1/e at h = L) -- what
  ``shadowing_field`` draws (``mission.simulate``, training data; kept so that the same seeds give
  the same bytes);
- ``exponential``: C(h) = sigma^2 exp(-h / L)      (Gudmundson's model; rough; 1/e at h = L) -- the
  usual fit to measured shadowing, and the kriging prior of ``mission.gap``.

``fit_variogram`` fits gamma(h) = n^2 + sigma^2 (1 - C(h) / sigma^2) (nugget n = white noise) to the
empirical semivariogram of residuals, for either family, with block-bootstrap confidence intervals;
it is what names "correlated shadowing" vs "white noise" on real flights.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter, gaussian_filter1d, map_coordinates
from scipy.optimize import nnls
from scipy.signal import lfilter
from scipy.special import ndtr

COVARIANCES = ("exponential", "gaussian")
# what a drawn shadowing is fixed to: the ground (``shadowing_field``: the same place, the same dB,
# whenever it is flown) or the flight's own path (``path_shadowing``: correlated along the track,
# independent on a later pass over the same ground)
SHADOWING_OVER = ("ground", "path")
# random Fourier waves of an exponential-covariance field drawn over the ground
# (``draw_shadowing``): enough that the sum looks Gaussian and its covariance is near exp(-h/L)
EXPONENTIAL_WAVES = 1000


def correlation(h: np.ndarray, corr_len_m: float, kind: str = "exponential") -> np.ndarray:
    """rho(h) = exp(-h / L) (exponential) or exp(-h^2 / L^2) (gaussian)."""
    h = np.asarray(h, dtype=float) / corr_len_m
    if kind == "exponential":
        return np.exp(-h)
    if kind == "gaussian":
        return np.exp(-h * h)
    raise ValueError(f"unknown covariance {kind!r} (expected {', '.join(COVARIANCES)})")


def pdist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distances between the rows of ``a`` (N, D) and ``b`` (M, D) -> (N, M).

    Column by column, in place: no (N, M, D) temporary (the kriged fields call it on thousands of
    samples against hundreds of cells); the squares add in the same order as a sum over the last
    axis, so the values are the same bit for bit."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d2 = np.zeros((len(a), len(b)))
    for j in range(a.shape[1]):
        dj = np.subtract.outer(a[:, j], b[:, j])
        dj *= dj
        d2 += dj
    return np.sqrt(d2, out=d2)


def shadowing_field(
    xy: np.ndarray,
    sigma_db: float,
    corr_m: float,
    rng: np.random.Generator,
    cells_per_corr: float = 4.0,
) -> np.ndarray:
    """Zero-mean Gaussian-covariance shadowing (dB) at positions ``xy`` (N, 2): one random field per
    call.

    White noise on a grid (``corr_m / cells_per_corr`` cells, at least 1 m) is smoothed by a
    Gaussian of ``corr_m / 2``, which gives the correlation ``exp(-d**2 / corr_m**2)`` (1/e at
    ``corr_m``), scaled to std ``sigma_db`` over the grid and read at ``xy`` by bilinear
    interpolation.  A UAV passing the same place twice sees the same shadowing, which independent
    per-sample noise cannot reproduce.
    """
    xy = np.asarray(xy, dtype=float)
    if sigma_db <= 0 or len(xy) == 0:
        return np.zeros(len(xy))
    if corr_m <= 0:
        raise ValueError(f"shadowing correlation distance must be > 0, got {corr_m}")
    res = max(corr_m / cells_per_corr, 1.0)
    s_cells = 0.5 * corr_m / res
    pad = 3.0 * corr_m
    lo = xy.min(axis=0) - pad
    shape = np.ceil((xy.max(axis=0) + pad - lo) / res).astype(int) + 1
    white = rng.standard_normal(tuple(shape))
    g = gaussian_filter(white, s_cells, mode="wrap")
    g *= sigma_db / max(float(g.std()), 1e-12)
    coords = ((xy - lo) / res).T
    return map_coordinates(g, coords, order=1, mode="nearest")


def path_length(pos: np.ndarray) -> np.ndarray:
    """Cumulative horizontal distance (m) along the samples ``pos`` (N, >= 2) in flight order."""
    xy = np.asarray(pos, dtype=float)[:, :2]
    if len(xy) == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def path_shadowing(
    pos: np.ndarray,
    sigma_db: float,
    corr_m: float,
    rng: np.random.Generator,
    cells_per_corr: float = 4.0,
    covariance: str = "gaussian",
) -> np.ndarray:
    """Zero-mean Gaussian-covariance shadowing (dB) along the flight's path: ``shadowing_field``'s
    draw in one dimension, over the cumulative horizontal distance flown (``path_length``), so the
    correlation is ``exp(-s**2 / corr_m**2)`` for samples ``s`` metres apart along the track
    (``covariance="exponential"``: ``exp(-s / corr_m)``, a first-order autoregression on the grid).

    Why: the gap diagnosis finds the real flights' residual correlated within a flight but not
    repeating over the same ground (``mission.gap.structure``: its own path's shadowing seen once,
    a gain changing over the flight); a field fixed to the ground makes a spiral's later rings see
    the same error again, which such a residual does not."""
    pos = np.asarray(pos, dtype=float)
    if sigma_db <= 0 or len(pos) == 0:
        return np.zeros(len(pos))
    if corr_m <= 0:
        raise ValueError(f"shadowing correlation distance must be > 0, got {corr_m}")
    s = path_length(pos)
    res = max(corr_m / cells_per_corr, 1.0)
    pad = int(np.ceil(3.0 * corr_m / res))
    n = int(np.ceil(s[-1] / res)) + 1 + 2 * pad
    if covariance == "exponential":
        rho = np.exp(-res / corr_m)
        e = rng.standard_normal(n)
        e[1:] *= np.sqrt(1.0 - rho * rho)
        g = lfilter([1.0], [1.0, -rho], e)  # x_k = rho x_(k-1) + sqrt(1 - rho^2) e_k, x_0 = e_0
    else:
        g = gaussian_filter1d(rng.standard_normal(n), 0.5 * corr_m / res, mode="wrap")
    g *= sigma_db / max(float(g.std()), 1e-12)
    return np.interp(s / res + pad, np.arange(n), g)


def draw_shadowing(
    pos: np.ndarray,
    sigma_db: float,
    corr_m: float,
    over: str,
    rng: np.random.Generator,
    marginal: Marginal | None = None,
    covariance: str = "gaussian",
) -> np.ndarray:
    """One flight's shadowing (dB) at its samples ``pos`` (N, >= 2, flight order), fixed to the
    ground or to the path (``SHADOWING_OVER``), of the ``covariance`` named (``COVARIANCES``; the
    exponential one on the ground is ``RandomField``'s, ``EXPONENTIAL_WAVES`` waves); with
    ``marginal``, mapped to that shape (``quantile_mapped``)."""
    if covariance not in COVARIANCES:
        raise ValueError(f"unknown covariance {covariance!r} (expected {', '.join(COVARIANCES)})")
    xy = np.asarray(pos, dtype=float)[:, :2]
    if over == "path":
        x = path_shadowing(pos, sigma_db, corr_m, rng, covariance=covariance)
    elif over == "ground" and covariance == "exponential":
        field = RandomField.draw(sigma_db, corr_m, rng, m=EXPONENTIAL_WAVES, kind="exponential")
        # in blocks of rows: an (N, waves) phase matrix of a 20 000-sample flight is 160 MB
        blocks = [field.at(xy[i : i + 4096]) for i in range(0, len(xy), 4096)]
        x = np.concatenate(blocks) if blocks else np.zeros(0)
    elif over == "ground":
        x = shadowing_field(xy, sigma_db, corr_m, rng)
    else:
        raise ValueError(f"shadowing over {over!r}: must be one of {', '.join(SHADOWING_OVER)}")
    return x if marginal is None or sigma_db <= 0 else quantile_mapped(x, sigma_db, marginal)


# a standardized marginal: probabilities p (increasing, in (0, 1)) and the quantiles q (mean 0,
# std 1) of the shape a drawn shadowing takes
Marginal = tuple[tuple[float, ...], tuple[float, ...]]


def quantile_mapped(x: np.ndarray, sigma_db: float, marginal: Marginal) -> np.ndarray:
    """``x``, a zero-mean Gaussian draw of std ``sigma_db``, mapped sample by sample to
    ``sigma_db`` times the standardized ``marginal`` (q at p, linear between, held beyond): a
    Gaussian copula, so the draw keeps its correlation's ranks and takes the marginal's shape.

    Why: the real flights' held-out residual is skewed to fades (p10 -15 to -23 dB, p90 +5 to
    +10 dB on four of the six), which a Gaussian draws as often up as down; a false peak of
    +20 dB is what misleads every method, a fade of -20 dB much less."""
    p, q = marginal
    return sigma_db * np.interp(ndtr(np.asarray(x, dtype=float) / sigma_db), p, q)


def standardized_marginal(r: np.ndarray, levels: int = 41) -> Marginal:
    """The standardized marginal of the residuals ``r`` (finite values; about their mean, over
    their std) at ``levels`` probabilities from 0.5 % to 99.5 %."""
    r = np.asarray(r, dtype=float)
    r = r[np.isfinite(r)]
    z = (r - r.mean()) / max(float(r.std()), 1e-12)
    p = np.linspace(0.005, 0.995, levels)
    return tuple(np.round(p, 6).tolist()), tuple(np.round(np.quantile(z, p), 6).tolist())


@dataclass(frozen=True, eq=False)
class RandomField:
    """A stationary Gaussian random field defined everywhere (random Fourier features, ``m`` waves).

    Frequencies are drawn from the covariance's spectrum: a bivariate Cauchy (exponential
    covariance) or a normal with std sqrt(2) / L (gaussian covariance); ``field_db(xy) = sigma
    sqrt(2/m) sum cos(w.xy + b)``. Unlike ``shadowing_field`` it can be evaluated at new positions
    later (held-out data, other flights).
    """

    sigma_db: float
    corr_len_m: float
    w: np.ndarray
    b: np.ndarray
    kind: str = "exponential"
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def draw(
        cls,
        sigma_db: float,
        corr_len_m: float,
        rng: np.random.Generator,
        m: int = 400,
        kind: str = "exponential",
    ) -> RandomField:
        z = rng.normal(size=(m, 2))
        if kind == "exponential":
            w = z / (corr_len_m * np.sqrt(rng.chisquare(1.0, size=(m, 1))))
        elif kind == "gaussian":
            w = z * (np.sqrt(2.0) / corr_len_m)
        else:
            raise ValueError(f"unknown covariance {kind!r} (expected {', '.join(COVARIANCES)})")
        return cls(sigma_db, corr_len_m, w, rng.uniform(0, 2 * np.pi, m), kind)

    def at(self, xy: np.ndarray) -> np.ndarray:
        """Field values (dB) at positions ``xy`` (N, 2)."""
        return (
            self.sigma_db
            * np.sqrt(2.0 / self.b.size)
            * np.cos(np.asarray(xy) @ self.w.T + self.b).sum(axis=1)
        )

    def field_db(self, flight: object, rx_xy: np.ndarray) -> np.ndarray:
        """``SpatialField`` protocol of ``mission.gap.pipeline`` (memoised by the query
        positions)."""
        key = (rx_xy.shape, hash(np.ascontiguousarray(rx_xy).tobytes()))
        if key not in self._cache:
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = self.at(rx_xy)
        return self._cache[key]


@dataclass
class Variogram:
    """A fitted semivariogram gamma(h) = n^2 + s^2 (1 - rho(h / L)), with bootstrap intervals (5-95
    %)."""

    kind: str
    sigma_db: float
    corr_len: float
    nugget_db: float
    sigma_ci: tuple[float, float] = (np.nan, np.nan)
    corr_len_ci: tuple[float, float] = (np.nan, np.nan)
    nugget_ci: tuple[float, float] = (np.nan, np.nan)
    lags: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gamma: np.ndarray = field(default_factory=lambda: np.zeros(0))
    counts: np.ndarray = field(default_factory=lambda: np.zeros(0))
    unit: str = "m"

    @property
    def correlated_fraction(self) -> float:
        """s^2 / (s^2 + n^2): the part of the residual variance that is correlated."""
        tot = self.sigma_db**2 + self.nugget_db**2
        return float(self.sigma_db**2 / tot) if tot > 0 else 0.0

    def as_dict(self) -> dict:
        return {
            "kind": self.kind,
            "sigma_db": self.sigma_db,
            "corr_len": self.corr_len,
            "unit": self.unit,
            "nugget_db": self.nugget_db,
            "sigma_ci_db": list(self.sigma_ci),
            "corr_len_ci": list(self.corr_len_ci),
            "nugget_ci_db": list(self.nugget_ci),
            "correlated_fraction": self.correlated_fraction,
            "lags": self.lags.tolist(),
            "gamma_db2": self.gamma.tolist(),
            "counts": self.counts.tolist(),
        }


def empirical_variogram(
    xy: np.ndarray, r: np.ndarray, edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Semivariance 0.5 mean (r_i - r_j)^2 of pairs binned by distance: (lag centres, gamma, pair
    counts).

    ``xy`` (N, d) may be positions (m) or times (N, 1) (s); O(N^2) memory: pass at most a few
    thousand points.
    """
    xy = np.asarray(xy, dtype=float).reshape(len(r), -1)
    i, j = np.triu_indices(len(r), 1)  # the pairs only, in the order of the full matrix's triangle
    d = xy[i] - xy[j]
    h = np.sqrt((d * d).sum(-1))
    g = 0.5 * (r[i] - r[j]) ** 2
    nb = len(edges) - 1
    b = np.digitize(h, edges) - 1
    ok = (b >= 0) & (b < nb) & (h > 0)  # resampled duplicates are not pairs
    cnt = np.bincount(b[ok], minlength=nb)[:nb]
    gm = np.bincount(b[ok], weights=g[ok], minlength=nb)[:nb] / np.maximum(cnt, 1)
    return 0.5 * (edges[:-1] + edges[1:]), gm, cnt


def _fit_model(
    lags: np.ndarray, gamma: np.ndarray, cnt: np.ndarray, kind: str, lengths: np.ndarray
) -> tuple[float, float, float, float]:
    """(weighted SSE, sigma, L, nugget): grid over L, non-negative linear fit of (n^2, s^2) per
    L."""
    use = cnt >= 10
    if use.sum() < 3:
        return np.inf, 0.0, float(lengths[0]), float(np.sqrt(max(np.mean(gamma), 0.0)))
    w = np.sqrt(cnt[use])
    best = (np.inf, 0.0, float(lengths[0]), 0.0)
    for L in lengths:
        A = np.column_stack([np.ones(use.sum()), 1.0 - correlation(lags[use], L, kind)])
        coef, res = nnls(A * w[:, None], gamma[use] * w)
        if res < best[0]:
            best = (float(res), float(np.sqrt(coef[1])), float(L), float(np.sqrt(coef[0])))
    return best


def fit_variogram(
    xy: np.ndarray,
    r: np.ndarray,
    rng: np.random.Generator,
    kind: str = "exponential",
    max_lag: float = 150.0,
    n_bins: int = 30,
    max_points: int = 1500,
    n_boot: int = 50,
    groups: np.ndarray | None = None,
    unit: str = "m",
    boot_points: int = 400,
) -> Variogram:
    """Fit ``kind`` (or ``"best"``: the family with the smaller weighted misfit) to residuals ``r``
    at ``xy``.

    ``xy``: positions (N, 2) in m, or times (N,) in s for the variogram along the path.  Points are
    sub-sampled to ``max_points``; ``groups`` (e.g. flight index) keeps pairs within a group only.
    Confidence intervals: the fit repeated on ``n_boot`` resamplings of whole lag-bins' pairs is too
    optimistic for 30 Hz tracks, so the points are resampled in contiguous blocks of 1/20 of the
    data.
    """
    r = np.asarray(r, dtype=float)
    xy = np.asarray(xy, dtype=float).reshape(len(r), -1)
    if groups is not None:  # separate groups by a distance no lag reaches
        xy = np.column_stack([xy, np.asarray(groups, dtype=float) * 1e9])
    if len(r) > max_points:
        sel = np.sort(rng.choice(len(r), max_points, replace=False))
        xy, r = xy[sel], r[sel]
    edges = np.linspace(0.0, max_lag, n_bins + 1)
    lengths = np.geomspace(max_lag / 100.0, 3.0 * max_lag, 40)
    kinds = COVARIANCES if kind == "best" else (kind,)

    def fit(x: np.ndarray, rr: np.ndarray) -> tuple[str, tuple[float, float, float, float], tuple]:
        lg = empirical_variogram(x, rr, edges)
        fits = {k: _fit_model(*lg, k, lengths) for k in kinds}
        k = min(fits, key=lambda q: fits[q][0])
        return k, fits[k], lg

    k, (_, s, L, n), (lags, gm, cnt) = fit(xy, r)
    boots = []
    nblk = 20
    # the intervals come from a thinned copy (every k-th point keeps the blocks)
    if len(r) > boot_points:
        thin = np.arange(0, len(r), int(np.ceil(len(r) / boot_points)))
        xy, r = xy[thin], r[thin]
    blocks = np.array_split(np.arange(len(r)), nblk)
    for _ in range(n_boot):
        pick = np.concatenate([blocks[j] for j in rng.integers(0, nblk, nblk)])
        _, (_, sb, Lb, nb_), _ = fit(xy[pick], r[pick])
        boots.append((sb, Lb, nb_))
    B = np.array(boots) if boots else np.full((1, 3), np.nan)

    est = (s, L, n)

    def ci(j: int) -> tuple[float, float]:
        """5-95 % of the replicates, shifted so that their median sits on the estimate (the
        replicates are fits to a thinned copy, whose estimator is noisier but not centred on the
        full-data estimate)."""
        q05, q50, q95 = np.quantile(B[:, j], [0.05, 0.5, 0.95])
        return max(0.0, float(est[j] + q05 - q50)), float(est[j] + q95 - q50)

    return Variogram(k, s, L, n, ci(0), ci(1), ci(2), lags, gm, cnt, unit)
