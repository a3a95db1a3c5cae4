"""Track-matched localizer (``localize --method matched``): inference learned on the flight's own
track.

After landing, ``n_draws`` transmitters are drawn uniformly over the rover area (the prior: the
transmitter can be anywhere in it) and simulated along the flown track, in cells, each under its own
draw of a physics family (``matched_sim``).  A small numpy network (``matched_net.SummaryNet``)
learns the transmitter position from the centred RSS-per-cell vector (offset-invariant); its output
is the summary of an ABC posterior (semi-automatic ABC): the ``k`` simulated transmitters whose
summary lies nearest the flight's, weighted by an Epanechnikov kernel, are posterior draws under the
family.  Cross-fitting keeps the reference summaries honest: the draws are split into ``folds``, a
net is trained on all folds but one, and only the held-out fold's draws (never seen by that net)
serve as its reference table.

Outputs: the posterior mean (point estimate), a kernel density of the posterior draws on a
``step_m`` grid (``uncertainty.Posterior``), its 50 % and 90 % HPD regions
(``uncertainty.hpd_regions``), and a self-check on ``n_check`` held-out simulated transmitters along
the same track (``extras["sim_check"]``: their error and region coverage).  With ``calibrate`` the
HPD masses are those that cover the held-out draws at the nominal rates (split conformal, per
flight, under the family; never fitted on real flights).  The held-out draws are set aside before
any net trains and are localized exactly as the flight is (every fold's net, every fold's reference
table, the union of their ABC draws): a check localized by one net only had narrower posteriors than
the flight's two-net union, and its masses made the flight's 50 % regions hold ~77 % of simulated
truths.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
from scipy.stats import gaussian_kde
from threadpoolctl import threadpool_limits

from mission.console import console, progress_bar
from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.evidence import conformal_quantile
from mission.geo import square_grid
from mission.localize import Estimate
from mission.localize.classical import _Base, as_flight, search_bounds
from mission.localize.matched_net import SummaryNet
from mission.localize.matched_sim import centred, draw_transmitters, simulate_track, track_cells
from mission.localize.selfcal import _p_outside_flown
from mission.localize.uncertainty import Posterior, hpd_regions
from mission.physics.family import PhysicsFamily, load_family

# The family drawn from when none is given: the shipped one (``load_family``), so a refitted
# ``mission/data/afar_family.json`` is picked up; a benchmark may point it at another family file.
DEFAULT_FAMILY: str | PhysicsFamily = "afar"
# Hyperparameters (constructor defaults) fixed on simulated suite flights (seed 77, afar family)
# before any real flight was scored: 40 000 draws (the held-out simulated error fell ~9 m from 20
# 000), 2 folds, 64 whitened principal components, two ReLU layers of 128, 40 epochs of batches of
# 128, k = 2 % of a fold, 5 m cells and grid.


@contextmanager
def rich_progress(enabled: bool | None = None):
    """A transient rich bar on stderr (shown only on a terminal unless ``enabled``) and its
    ``(description, done, total)`` callback."""
    con = console(stderr=True)
    show = con.is_terminal if enabled is None else enabled
    with progress_bar("{task.description:<24}", con, disable=not show) as bar:
        task = bar.add_task("matched", total=1)

        def tick(desc: str, done: int, total: int) -> None:
            bar.update(task, description=desc[:24], completed=done, total=total)

        yield tick


@contextmanager
def _given(progress):
    """A caller's callback (``False``: none) in the shape of ``rich_progress``."""
    yield None if progress is False else progress


def abc_draws(s_ref: np.ndarray, s_obs: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the ``k`` reference summaries nearest ``s_obs`` and their Epanechnikov weights."""
    d2 = ((s_ref - s_obs) ** 2).sum(axis=1)
    k = int(min(max(k, 2), len(d2) - 1))
    idx = np.argpartition(d2, k)[: k + 1]
    idx = idx[np.argsort(d2[idx])]
    h2 = max(float(d2[idx[-1]]), 1e-12)
    w = 1.0 - d2[idx[:-1]] / h2
    return idx[:-1], np.maximum(w, 1e-6)


def kde_of(pts: np.ndarray, w: np.ndarray, floor_m: float) -> gaussian_kde:
    """The draws' weighted Gaussian kernel density (scipy's ``gaussian_kde``: Scott's factor on the
    weighted draws' covariance, so the kernel follows an elongated posterior), widened where needed
    so its narrowest axis is at least ``floor_m`` (the grid step: a narrower kernel would fall
    between the grid's points)."""
    k = gaussian_kde(pts.T, weights=w)
    narrowest = float(np.sqrt(np.linalg.eigvalsh(k.covariance)[0]))
    if narrowest < floor_m:
        k.set_bandwidth(k.factor * floor_m / max(narrowest, 1e-9))
    return k


def hpd_level_of(truth: np.ndarray, density: gaussian_kde, pts: np.ndarray, w: np.ndarray) -> float:
    """The smallest HPD mass whose set (under the draws' kernel ``density``) holds ``truth``: the
    weight of the draws denser than the truth's point."""
    dens = density(pts.T)
    return float(w[dens > density(truth[:, None])[0]].sum() / w.sum())


def conformal_mass(levels_seen: np.ndarray, level: float) -> float:
    """The HPD mass that holds the truth in a fraction ``level`` of held-out draws: the
    split-conformal quantile of their HPD levels (``evidence.conformal_quantile``), kept inside
    (0.02, 0.999) so a region exists."""
    return float(np.clip(conformal_quantile(levels_seen, level), 0.02, 0.999))


class MatchedLocalizer(_Base):
    """Track-matched ABC localizer (module docstring); configuration in the constructor,
    scikit-learn style.

    ``area``: an ``Area`` (the prior and the search polygon) or a box; None = the flight's box grown
    by ``margin_m``.  ``family``: a ``PhysicsFamily``, a name/path for ``load_family``, or None
    (``DEFAULT_FAMILY``). ``progress``: a ``(description, done, total)`` callback, None for a rich
    bar on a terminal, False for none.
    """

    name = "matched"

    def __init__(
        self,
        area=None,
        family: str | PhysicsFamily | None = None,
        n_draws: int = 40000,
        cell_m: float = 5.0,
        tx_height_m: float = DEFAULT_TX_HEIGHT_M,
        margin_m: float = 60.0,
        step_m: float = 5.0,
        folds: int = 2,
        k_frac: float = 0.02,
        n_pca: int = 64,
        hidden: tuple[int, ...] = (128, 128),
        epochs: int = 40,
        batch: int = 128,
        lr: float = 2e-3,
        whiten: bool = True,
        group: int = 64,
        n_check: int = 200,
        calibrate: bool = True,
        levels: tuple[float, ...] = (0.5, 0.9),
        min_cells: int = 8,
        seed: int = 0,
        progress=None,
    ) -> None:
        self.area = area
        self.family = family
        self.n_draws = int(n_draws)
        self.cell_m = float(cell_m)
        self.tx_height_m = float(tx_height_m)
        self.margin_m = float(margin_m)
        self.step_m = float(step_m)
        self.folds = int(folds)
        self.k_frac = float(k_frac)
        self.n_pca = int(n_pca)
        self.hidden = tuple(hidden)
        self.epochs = int(epochs)
        self.batch = int(batch)
        self.lr = float(lr)
        self.whiten = bool(whiten)
        self.group = int(group)
        self.n_check = int(n_check)
        self.calibrate = bool(calibrate)
        self.levels = tuple(levels)
        self.min_cells = int(min_cells)
        self.seed = int(seed)
        self.progress = progress

    def _family(self) -> PhysicsFamily:
        fam = DEFAULT_FAMILY if self.family is None else self.family
        return fam if isinstance(fam, PhysicsFamily) else load_family(fam)

    def _check(self, f) -> None:
        if self.folds < 2 or self.n_draws < 20 * self.folds:
            raise InputError(
                f"matched needs >= 2 folds and >= {20 * self.folds} draws, got {self.folds} folds "
                f"and {self.n_draws} draws",
                field="n_draws",
            )
        for name, a in (("rss_dbm", f.rss_dbm), ("position", f.enu_m)):
            bad = ~np.isfinite(a).reshape(len(f.rss_dbm), -1).all(axis=1)
            if bad.any():
                raise InputError(
                    f"{int(bad.sum())} samples with a non-finite {name} (first: sample "
                    f"{int(np.argmax(bad))})",
                    field=name,
                )

    def predict(self, flight, origin=None) -> Estimate:
        f = as_flight(flight, origin)
        self._check(f)
        track = track_cells(f, self.cell_m)
        if len(track) < self.min_cells:
            raise InputError(
                f"only {len(track)} distinct {self.cell_m:g} m cells flown: too few to localize "
                f"(need {self.min_cells})"
            )

        # one BLAS thread: the products are small, and threads that wait for a busy core cost 10-30x
        # more
        with (
            threadpool_limits(1),
            rich_progress() if self.progress is None else _given(self.progress) as tick,
        ):
            return self._predict(f, track, tick)

    def _predict(self, f, track, tick) -> Estimate:
        fam = self._family()
        rng = np.random.default_rng(self.seed)
        box, poly = search_bounds(self.area, f.enu_m, self.margin_m)
        tx = draw_transmitters(poly, box, self.n_draws, rng)
        x = centred(simulate_track(track, fam, tx, self.tx_height_m, rng, self.group, tick)).astype(
            np.float32
        )
        x_obs = centred(track.rss_dbm).astype(np.float32)
        n_cal = min(self.n_check, self.n_draws // 10) if self.n_check >= 10 else 0
        # held out of every net and table
        cal = np.sort(rng.choice(self.n_draws, n_cal, replace=False))
        fold = np.full(self.n_draws, -1)
        ref = np.ones(self.n_draws, dtype=bool)
        ref[cal] = False
        fold[ref] = np.arange(int(ref.sum())) % self.folds
        s_ref = np.full((self.n_draws, 2), np.nan)
        s_obs = np.empty((self.folds, 2))
        s_cal = np.empty((self.folds, n_cal, 2))
        for j in range(self.folds):
            net = SummaryNet(
                self.n_pca, self.hidden, self.epochs, self.batch, self.lr, whiten=self.whiten
            )
            train = ref & (fold != j)
            net.fit(x[train], tx[train], rng, tick, f"training net {j + 1}/{self.folds}")
            s_ref[fold == j] = net.predict(x[fold == j])
            s_obs[j] = net.predict(x_obs)
            s_cal[j] = net.predict(x[cal]) if n_cal else s_cal[j]
        k = max(int(self.k_frac * self.n_draws / self.folds), 10)
        idx, w = self._abc(s_ref, s_obs, fold, k)
        pts = tx[idx]
        density = kde_of(pts, w, self.step_m)
        check = self._self_check(tx, s_ref, s_cal, cal, fold, k)
        masses = (
            {lev: conformal_mass(check["hpd_levels"], lev) for lev in self.levels}
            if self.calibrate
            else {}
        )
        grid = square_grid(box, self.step_m)
        flat = grid.reshape(-1, 2)
        dens = density(flat.T)
        if poly is not None:
            dens = dens * poly.contains(flat)
        if not dens.sum() > 0:
            dens = np.ones(len(flat))
        post = Posterior((dens / dens.sum()).reshape(grid.shape[:2]), grid)
        regions = hpd_regions(post, grid, self.levels, masses)
        xy = (w[:, None] * pts).sum(axis=0) / w.sum()
        p_out = _p_outside_flown(post, grid, f.enu_m)
        extras = dict(
            family=fam.name,
            n_draws=self.n_draws,
            n_cells=len(track),
            cell_m=self.cell_m,
            tx_height_m=self.tx_height_m,
            abc_draws=int(len(idx)),
            kde_axes_m=[float(v) for v in np.sqrt(np.linalg.eigvalsh(density.covariance))],
            summary_xy_m=[float(v) for v in s_obs.mean(axis=0)],
            search_box=[float(v) for v in box],
            sim_check={k_: v for k_, v in check.items() if k_ != "hpd_levels"},
            regions=regions,
            p_outside_flown_area=p_out,
            seed=self.seed,
        )
        est = self._estimate(
            float(xy[0]),
            float(xy[1]),
            f"track-matched ABC under physics family {fam.name}",
            **extras,
        )
        if p_out >= 0.5:
            est.add_note(
                "the transmitter probably lies outside the flown area (posterior mass "
                f"{100 * p_out:.0f} % "
                "outside it): the estimate is an extrapolation"
            )
        est.posterior = post
        return est

    def _abc(self, s_ref: np.ndarray, s_obs: np.ndarray, fold: np.ndarray, k: int):
        """Posterior draws: each fold's ``k`` nearest reference summaries to that fold's net's
        summary."""
        idx, w = [], []
        for j in range(self.folds):
            ref = np.flatnonzero(fold == j)
            i, ww = abc_draws(s_ref[ref], s_obs[j], k)
            idx.append(ref[i])
            w.append(ww)
        return np.concatenate(idx), np.concatenate(w)

    def _self_check(
        self,
        tx: np.ndarray,
        s_ref: np.ndarray,
        s_cal: np.ndarray,
        cal: np.ndarray,
        fold: np.ndarray,
        k: int,
    ) -> dict:
        """Error and HPD levels of the held-out simulated transmitters ``cal`` along this track
        (never trained on, in no reference table), each localized exactly as the flight is: its
        summary under every fold's net (``s_cal``, one row per fold), the union of every fold's ABC
        draws."""
        n = len(cal)
        if n < 10:
            return {"n": 0, "hpd_levels": np.zeros(0)}
        errs, lev = np.empty(n), np.empty(n)
        for c, q in enumerate(cal):
            i, w = self._abc(s_ref, s_cal[:, c], fold, k)
            pts = tx[i]
            est = (w[:, None] * pts).sum(axis=0) / w.sum()
            errs[c] = float(np.hypot(*(est - tx[q])))
            lev[c] = hpd_level_of(tx[q], kde_of(pts, w, self.step_m), pts, w)
        held = fold >= 0
        out = {
            "n": n,
            "mean_error_m": float(errs.mean()),
            "median_error_m": float(np.median(errs)),
            "summary_median_error_m": float(np.median(np.hypot(*(s_ref[held] - tx[held]).T))),
            "hpd_levels": lev,
        }
        out.update({f"coverage_{round(100 * lv)}": float((lev < lv).mean()) for lv in self.levels})
        return out
