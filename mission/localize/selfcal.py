"""Self-calibrating model-based localizer: the per-flight nuisance is profiled out, not taken from a
preset.

Why: a physics preset fitted on two teams' flights (one antenna heading, one mounting) did not carry
over to other teams' flights.  Here every candidate transmitter position is scored under a set of
antenna *hypotheses* (the measured RM-WB1-DN pattern hanging upside down or upright at every
mounting heading in ``heading_step_deg`` steps, a vertical dipole, vertical dipoles at both ends,
an isotropic antenna), each with
its own free RSS offset, and the best hypothesis is kept per candidate (profile likelihood).  A UAV
dipole is fixed to the body and tilts with it (each cell's mean body axis); the measured pattern
follows the heading alone.  The
distance law is free space (``-20 log10 d``): on the real AFAR flights a free exponent absorbed the
antenna's elevation pattern and moved estimates (``models/README.md``).

Correlated shadowing: the flight is first averaged into ``cell_m`` square cells in the horizontal
plane, one set per cruise altitude (``mission.cells.cell_average``), so that a slow pass or a hover
does not count its spot many times, and the likelihood is tempered to the number of *independent*
cells, ``n_eff = covered area / (pi corr_m^2)`` (exponential shadowing correlation length
``corr_m``), so thousands of correlated samples do not count as independent evidence.  The tempered
profile likelihood over the search grid is the posterior from which
:mod:`mission.localize.uncertainty` draws the 50 % and 90 % regions.

Model (per cell m, candidate k, hypothesis h)::

    P_m = c_kh + G_h(el_km, az_km) - 20 log10 d_km + e_m          # free space + UAV antenna, c free
    SSR_kh = sum_m (P_m - G_h - (-20 log10 d_km) - c_kh)^2,       c_kh = the mean (least squares)
    log p(k) = logsumexp_h(-0.5 tau SSR_kh / s^2),  s^2 = min SSR / (M - 1),  tau = n_eff / M
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from mission.cells import ALTITUDE_GAP_M, Cells, cell_average
from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.geo import Area, square_grid
from mission.localize import Estimate
from mission.localize.classical import _Base, as_flight, search_bounds
from mission.localize.uncertainty import grid_posterior, hpd_regions
from mission.physics.antenna import Dipole, Pattern, rm_wb1_dn
from mission.physics.geometry import heading_frame_angles, link_delta
from mission.samples import FlightSamples

HYPOTHESIS_KINDS = ("measured-flipped", "measured", "dipole", "dipole-pair", "isotropic")
# Shadowing correlation length (temperature), calibrated on the unseen-flight benchmark (`afar`
# family), and the HPD masses that cover the truth at the nominal rates, recalibrated on the
# reality-fitted benchmark (its family mission/data/afar_family.json from rfsl gap --family, seeds
# 2027 (200), 2028 (100), 2026 (100), 400 flights; benchmarks/calibrate_regions.py --suite-dirs):
# the HPD sets of mass 0.339 / 0.870 covered the truth in 50.8 % / 89.8 % of held-out flights
# (5-fold; leave-one-seed-out 45-57 % / 87-94 %) and on the six real flights 3 / 6 of 6 (the
# afar-family masses 0.511 / 0.954 covered 61 / 94 % of the fitted benchmark: too wide).
CORR_M = 15.0
CALIBRATED_MASS = {0.5: 0.339, 0.9: 0.870}


def corr_is_default(corr_m: float) -> bool:
    """The calibrated masses hold only for the calibrated temperature."""
    return abs(corr_m - CORR_M) < 1e-9


def antenna_hypotheses(
    kinds: tuple[str, ...] = HYPOTHESIS_KINDS, heading_step_deg: float = 30.0
) -> list[tuple[str, Pattern | None, float, bool]]:
    """The UAV antenna hypotheses as (label, pattern or None for isotropic, mounting heading rad,
    flipped)."""
    out: list[tuple[str, Pattern | None, float, bool]] = []
    heads = np.arange(0.0, 360.0, float(heading_step_deg))
    for kind in kinds:
        if kind in ("measured-flipped", "measured"):
            flipped = kind == "measured-flipped"
            for h in heads:
                out.append(
                    (
                        f"RM-WB1-DN {'upside down' if flipped else 'upright'} heading {h:.0f} deg",
                        rm_wb1_dn(),
                        float(np.radians(h)),
                        flipped,
                    )
                )
        elif kind == "dipole":
            out.append(("vertical dipole", Dipole(), 0.0, False))
        elif kind == "dipole-pair":
            out.append(("vertical dipoles, UAV and transmitter", DipolePair(), 0.0, False))
        elif kind == "isotropic":
            out.append(("isotropic", None, 0.0, False))
        else:
            raise InputError(
                f"unknown antenna hypothesis {kind!r} (known: {', '.join(HYPOTHESIS_KINDS)})",
                field="hypotheses",
            )
    return out


@dataclass(frozen=True)
class DipolePair(Dipole):
    """Vertical dipoles at the UAV and at the transmitter, as one hypothesis: the link's gain
    ``2 G_dipole(el)`` (SPEC section 3), since each upright dipole sees the other at the same
    elevation magnitude and the pattern is symmetric in elevation.

    Why: the transmitter was taken as isotropic, but the paper's physics (what ``fly-mission``
    simulates against a SITL) has dipoles at both ends, so straight above the transmitter the RSS
    falls into two nulls, not one; a search without this hypothesis reads a pass overhead as far
    from the transmitter (ArduCopter SITL seed 1, docs/adaptive.md).
    """

    name: str = "dipole pair"

    def gain_dbi(self, el, az=None):
        return self.link_gain_dbi(el, el)

    def link_gain_dbi(self, el_tx, el_uav):
        """The link's gain with each dipole's own elevation of the link: the transmitter's seen
        from the level frame, the UAV's from its tilted body (``uav_elevation``)."""
        return Dipole.gain_dbi(self, el_tx) + Dipole.gain_dbi(self, el_uav)


def _geometry(cand_xy: np.ndarray, cells: Cells, tx_height_m: float) -> tuple[np.ndarray, ...]:
    """(K, M) float32 free-space path gain -20 log10 d, platform elevation and body azimuth of the
    transmitter, and its elevation above the tilted body's plane (``uav_elevation``).

    Body azimuth uses the heading only (the receiver antenna hangs below the body; roll and pitch
    did not help the measured pattern on real flights, ``rfsl gap``), clockwise from the nose;
    elevation is negative below the UAV.
    """
    tx = np.column_stack([cand_xy, np.full(len(cand_xy), float(tx_height_m))])
    dx, dy, dz = link_delta(tx[:, None, :], cells.enu_m[None, :, :], np.float32)
    dh2 = dx * dx + dy * dy
    d2 = dh2 + dz * dz
    pg = np.float32(-10.0) * np.log10(d2)  # -20 log10 d_los
    el, az = heading_frame_angles(
        dx, dy, dz, cells.yaw_rad[None, :].astype(np.float32), np.sqrt(dh2)
    )
    return pg, el, az, uav_elevation(dx, dy, dz, d2, cells, el)


def uav_elevation(dx, dy, dz, d2, cells: Cells, el: np.ndarray) -> np.ndarray:
    """Elevation of the link (dx, dy, dz) = p_tx - p_uav above the plane normal to each cell's mean
    body up axis: ``asin(u . a / |u|)``, what a dipole fixed upright to the body sees.

    Why: multirotors cruise nose down (ArduCopter SITL a median -14 deg of pitch, PX4 SITL about
    -28 deg) and the mission's physics tilts the UAV's dipole with the body, so an upright dipole
    puts its null where a tilted one does not.  Cells without an axis (no attitude) are level:
    ``el`` itself.
    """
    if cells.axis_enu is None:
        return el
    a = cells.axis_enu.astype(np.float32)
    s = (dx * a[:, 0] + dy * a[:, 1] + dz * a[:, 2]) / np.sqrt(d2)
    return np.arcsin(np.clip(s, np.float32(-1.0), np.float32(1.0)))


class GainLookup:
    """A pattern resampled once to a 1-degree (elevation x azimuth) table, looked up by nearest
    index.

    Why: every candidate x cell x mounting heading needs a gain; with integer indices computed once
    per call a hypothesis costs one modular shift and one gather instead of a bilinear interpolation
    (the 3-degree measured table's bilinear values are kept to about 0.5 dB).
    """

    def __init__(self, pat: Pattern) -> None:
        e, a = np.meshgrid(
            np.radians(np.arange(-90.0, 90.5, 1.0)),
            np.radians(np.arange(0.0, 360.0, 1.0)),
            indexing="ij",
        )
        t = pat.gain_dbi(e, a).astype(np.float32)  # (181, 360), antenna frame
        self.upright = t
        self.flipped = t[::-1]  # el -> -el (180 deg about the antenna's x axis)
        self._mounted: dict[tuple[int, bool], np.ndarray] = {}

    def mounted(self, heading_deg: int, flipped: bool) -> np.ndarray:
        """The flat (181 * 360,) table indexed by platform ``(el + 90) * 360 + az`` (az clockwise
        from the nose) for one mounting: the antenna-frame column of platform azimuth ``a`` is ``a -
        heading`` (flipped) or ``heading - a`` (upright), mod 360 (``mount_angles``).  Made once per
        mounting."""
        key = (heading_deg, flipped)
        if key not in self._mounted:
            a = np.arange(360)
            cols = np.mod(a - heading_deg, 360) if flipped else np.mod(heading_deg - a, 360)
            self._mounted[key] = np.ascontiguousarray(
                (self.flipped if flipped else self.upright)[:, cols]
            ).ravel()
        return self._mounted[key]

    def gain_db(self, i_flat: np.ndarray, heading_deg: int, flipped: bool) -> np.ndarray:
        """Gain at flat platform indices ``(el + 90) * 360 + az`` for one mounting (one gather)."""
        return self.mounted(heading_deg, flipped)[i_flat]


class GainTables:
    """The 1-degree gain tables (``GainLookup``) of the patterns one grid has met, each made once:
    owned by the grid (``SelfCalibratingGrid.gain_tables``), so its two searches per flight and its
    later flights share them."""

    def __init__(self) -> None:
        # a pattern is found by identity (patterns hold arrays)
        self._made: list[tuple[Pattern, GainLookup]] = []

    def __call__(self, pat: Pattern) -> GainLookup:
        for p, table in self._made:
            if p is pat:
                return table
        table = GainLookup(pat)
        self._made.append((pat, table))
        return table


def flat_index(el: np.ndarray, az: np.ndarray) -> np.ndarray:
    """Index ``(el + 90) * 360 + az`` (whole degrees) into a ``GainLookup`` table, from angles in
    rad."""
    return (np.rint(np.degrees(el)).astype(np.int32) + 90) * 360 + np.mod(
        np.rint(np.degrees(az)).astype(np.int32), 360
    )


def hypothesis_residuals(
    base: np.ndarray,
    el: np.ndarray,
    az: np.ndarray,
    hyps,
    tables: GainTables | None = None,
    el_uav: np.ndarray | None = None,
):
    """Yield ``base - G_h`` (K, M) for each UAV-antenna hypothesis h, the platform angles from
    ``_geometry``; tabulated patterns are looked up in ``tables`` (a fresh ``GainTables`` when
    None).  The dipoles' UAV side takes ``el_uav``, the elevation above the tilted body's plane
    (None: ``el``, a level body); the measured patterns keep the heading frame."""
    tables = GainTables() if tables is None else tables
    el_uav = el if el_uav is None else el_uav
    idx = None
    for _, pat, head, flipped in hyps:
        if pat is None:
            yield base
        elif isinstance(pat, DipolePair):  # the transmitter's dipole upright, the UAV's tilted
            yield base - pat.link_gain_dbi(el, el_uav).astype(np.float32)
        elif isinstance(pat, Dipole):  # azimuth-symmetric, one hypothesis: the reference formula
            yield base - pat.gain_dbi(el_uav).astype(np.float32)
        else:
            if idx is None:
                idx = flat_index(el, az)
            yield base - tables(pat).gain_db(idx, int(round(np.degrees(head))) % 360, flipped)


def hypothesis_ssr(
    cand_xy: np.ndarray, cells: Cells, hyps, tx_height_m: float, tables: GainTables | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares residual sum SSR (H, K) and fitted offset c (H, K) for every hypothesis and
    candidate (``tables``: the caller's gain tables, see ``hypothesis_residuals``)."""
    pg, el, az, el_uav = _geometry(cand_xy, cells, tx_height_m)
    y = cells.rss_dbm.astype(np.float32)[None, :]
    ssr = np.empty((len(hyps), len(cand_xy)))
    off = np.empty((len(hyps), len(cand_xy)))
    for i, r in enumerate(hypothesis_residuals(y - pg, el, az, hyps, tables, el_uav)):
        c = r.mean(axis=1)
        off[i] = c
        ssr[i] = np.einsum("km,km->k", r, r) - r.shape[1] * c.astype(np.float64) ** 2
    return np.maximum(ssr, 0.0), off


class SelfCalibratingGrid(_Base):
    """Grid search with per-candidate profiled antenna hypothesis and offset, on cell-averaged RSS.

    ``area``: an ``Area`` (candidates inside its polygon) or ``(xmin, ymin, xmax, ymax)``; None =
    the flight's box grown by ``margin_m``.  ``corr_m`` sets the likelihood's temperature (module
    docstring) and with it the width of the uncertainty regions; its default was calibrated on the
    unseen-flight benchmark (``models/README.md``). ``altitude_gap_m``: heights further apart than
    this are cruise altitudes with cells of their own (inf: one).
    """

    name = "selfcal"

    def __init__(
        self,
        area=None,
        margin_m: float = 60.0,
        cell_m: float = 5.0,
        step_m: float = 5.0,
        refine_m: float = 1.0,
        tx_height_m: float = DEFAULT_TX_HEIGHT_M,
        heading_step_deg: float = 30.0,
        hypotheses: tuple[str, ...] = HYPOTHESIS_KINDS,
        corr_m: float = CORR_M,
        min_cells: int = 8,
        levels: tuple[float, ...] = (0.5, 0.9),
        masses: dict[float, float] | None = None,
        altitude_gap_m: float = ALTITUDE_GAP_M,
    ) -> None:
        self.area = area
        self.margin_m = float(margin_m)
        self.cell_m = float(cell_m)
        self.step_m = float(step_m)
        self.refine_m = float(refine_m)
        self.tx_height_m = float(tx_height_m)
        self.heading_step_deg = float(heading_step_deg)
        self.hypotheses = tuple(hypotheses)
        self.corr_m = float(corr_m)
        self.min_cells = int(min_cells)
        self.levels = tuple(levels)
        self.altitude_gap_m = float(altitude_gap_m)
        self.masses = (
            dict(masses)
            if masses is not None
            else dict(CALIBRATED_MASS)
            if corr_is_default(corr_m)
            else {}
        )
        self.gain_tables = GainTables()  # the hypotheses' pattern tables, made on first use

    def _candidates(
        self, f: FlightSamples
    ) -> tuple[np.ndarray, tuple[float, float, float, float], object]:
        box, poly = search_bounds(self.area, f.enu_m, self.margin_m)
        return square_grid(box, self.step_m), box, poly

    def predict(self, flight, origin=None) -> Estimate:
        f = as_flight(flight, origin)
        cells = cell_average(f, self.cell_m, self.altitude_gap_m)
        if len(cells) < self.min_cells:
            raise InputError(
                f"only {len(cells)} distinct {self.cell_m:g} m cells flown: too few to localize "
                f"(need {self.min_cells})"
            )
        hyps = antenna_hypotheses(self.hypotheses, self.heading_step_deg)
        grid, box, poly = self._candidates(f)
        flat = grid.reshape(-1, 2)
        valid = np.ones(len(flat), dtype=bool) if poly is None else poly.contains(flat)
        if not valid.any():
            valid[:] = True
        ssr, off = hypothesis_ssr(flat[valid], cells, hyps, self.tx_height_m, self.gain_tables)
        m = len(cells)
        s2 = max(float(ssr.min()) / max(m - 1, 1), 1e-6)
        n_eff = max(cells.area_m2 / (np.pi * self.corr_m**2), 2.0)
        tau = min(n_eff / m, 1.0)
        logp = np.full((len(hyps), len(flat)), -np.inf)
        logp[:, valid] = -0.5 * tau * ssr / s2
        post = grid_posterior(logp, grid.shape[:2])
        # point estimate: the best candidate, refined on a fine grid under its three best hypotheses
        k = int(np.argmin(ssr.min(axis=0)))
        best_h = np.argsort(ssr[:, k])[:3]
        c0 = flat[valid][k]
        s = self.step_m
        fine = c0[None, :] + square_grid((-s, -s, s, s), self.refine_m).reshape(-1, 2)
        fssr, foff = hypothesis_ssr(
            fine, cells, [hyps[i] for i in best_h], self.tx_height_m, self.gain_tables
        )
        j = np.unravel_index(int(np.argmin(fssr)), fssr.shape)
        x, y = fine[j[1]]
        h = int(best_h[j[0]])
        regions = hpd_regions(post, grid, self.levels, self.masses)
        p_out = _p_outside_flown(post, grid, f.enu_m)
        extras = dict(
            antenna=hyps[h][0],
            offset_db=float(foff[j]),
            residual_rms_db=float(np.sqrt(fssr[j] / m)),
            n_cells=m,
            n_eff=float(n_eff),
            cell_m=self.cell_m,
            tx_height_m=self.tx_height_m,
            search_box=[float(v) for v in box],
            regions=regions,
            p_outside_flown_area=p_out,
        )
        est = self._estimate(x, y, "free space + profiled UAV antenna", **extras)
        if p_out >= 0.5:
            est.add_note(
                "the transmitter probably lies outside the flown area (posterior mass "
                f"{100 * p_out:.0f} % "
                "outside it): the estimate is an extrapolation"
            )
        est.posterior = post
        return est


def flown_area(enu: np.ndarray) -> Area | None:
    """The flown area: the convex hull of the UAV track (None for a degenerate track)."""
    xy = enu[:, :2]
    try:
        return Area("flown area", xy[ConvexHull(xy).vertices])
    except (QhullError, ValueError):
        return None


def _p_outside_flown(post, grid: np.ndarray, enu: np.ndarray, grow_m: float = 10.0) -> float:
    """Posterior mass outside the flown area grown by ``grow_m`` (NaN for a degenerate track)."""
    fa = flown_area(enu)
    if fa is None:
        return float("nan")
    pts = grid.reshape(-1, 2)
    near = fa.contains(pts) | (fa.edge_distance(pts) <= grow_m)
    return float(post.prob.ravel()[~near].sum())
