"""An independent flight generator for the gap self-test: written here from the formulas, not via
mission.physics.

Why: a self-test that generates its flights with the library it diagnoses with can only find what
the library already contains, with the library's own conventions.  This generator shares nothing
with ``mission.physics`` (only numpy): trajectories, attitude, the two-ray channel with vertical
dipoles (SPEC section 3, paper eq. 1), and one withheld effect per case, including effects no
candidate names (effect: truth -> the name the diagnosis is expected to give):

- ``none``: nothing -> nothing
- ``legs``: eqs. 8-9: beta 0.5-0.7, legs 39/150/270 +-5 deg, dep_b < 10 deg; rover near a corner ->
  leg_shadowing
- ``ground``: ground permittivity 10-25, 5 mS/m (the base assumes 2, lossless) -> ground_reflection
- ``ripple``: UAV antenna gain + A cos(3 (az_b - phi)), A 2-2.5 dB (4-5 dB peak to peak) ->
  rx_gain_map
- ``notch``: UAV gain - 10 dB exp(-(az_b - phi)^2 / 2 (15 deg)^2), phi an azimuth flown ->
  rx_gain_map
- ``tx_azimuth``: rover antenna gain + 3 dB cos(az_w - phi) over compass azimuth -> tx_gain_map
- ``shadowing``: exponential-covariance ground field, sigma 4 dB, L 30-60 m, one per flight ->
  spatial_shadowing
- ``timing``: RSS stamped late by 0.5-1.0 s -> time_offset
- ``nadir``: UAV gain - 8 dB exp(-(dep_b - 75 deg)^2 / 2 (8 deg)^2), any azimuth; the usual flights
  -> near_nadir
- ``nadir_over``: the same loss; both flights: stars of 5 (``passes``) passes over the rover ->
  near_nadir
- ``drift``: a receiver warming up: gain A (1 - exp(-t / 120 s)), A 3-4 dB, sign per flight ->
  time_drift
- ``step``: a gain step of 2.5-3 dB (sign per flight) at an event in the middle half (*) ->
  time_drift
- ``legs_far``: eqs. 8-9, a quad's 4 legs, below 8 deg depression, far from the rover (**) ->
  body-fixed

(*) at a turn of the lawnmower; the spiral has no sharp turn there, so its log records the switch as
a phase change (``mission`` -> ``adaptive``).  (**) legs at 45/135/225/315 deg, 7 deg half width,
beta 0.5-0.7; the rover mid-way along an edge (20-60 m in), so the legs act only over the far half
of the field (> 140-250 m); "body-fixed": ``leg_shadowing`` or ``rx_gain_map`` (``BODY_FIXED``).

The base model the diagnosis starts from is two-ray + vertical dipoles + (roll, pitch, yaw)
attitude, ground permittivity 2, P_t 41 dBm, 3.32 GHz; each flight gets an unknown receiver offset
and 1 dB white noise.
"""

from __future__ import annotations

import numpy as np

from mission.gap.align import align
from mission.gap.candidates import library
from mission.gap.fit import FitConfig, make_folds
from mission.gap.pipeline import Pipeline
from mission.gap.power import power_statement
from mission.gap.spatial import usable_candidates
from mission.gap.stats import block_length
from mission.gap.structure import identify
from mission.gap.temporal import time_power_statement
from mission.physics import Attitude, make_model
from mission.robust import offset_residual
from mission.samples import FlightSamples

C_LIGHT = 299_792_458.0
FC_HZ = 3.32e9
PT_DBM = 41.0
LAMBDA_M = C_LIGHT / FC_HZ
EPS0 = 8.8541878128e-12
LEGS_DEG = (39.0, 150.0, 270.0)
# ``legs_far``: a quad's four legs, a layout the library does not name
QUAD_LEGS_DEG = (
    45.0,
    135.0,
    225.0,
    315.0,
)
TX_HEIGHT_M = (
    1.5  # the rover antenna (this generator shares nothing with mission.*, not even its defaults)
)
EFFECTS = (
    "none",
    "legs",
    "ground",
    "ripple",
    "notch",
    "tx_azimuth",
    "shadowing",
    "timing",
    "nadir",
    "nadir_over",
    "drift",
    "step",
    "legs_far",
)
EXPECTED = {
    "none": None,
    "legs": "leg_shadowing",
    "ground": "ground_reflection",
    "ripple": "rx_gain_map",
    "notch": "rx_gain_map",
    "tx_azimuth": "tx_gain_map",
    "shadowing": "spatial_shadowing",
    "timing": "time_offset",
    "nadir": "near_nadir",
    "nadir_over": "near_nadir",
    "drift": "time_drift",
    "step": "time_drift",
    "legs_far": "leg_shadowing",
}
# a body-fixed effect the library has no exact name for is diagnosed when a body-frame candidate is
# named first
BODY_FIXED = ("leg_shadowing", "rx_gain_map")


# ------------------------------------------------------------------------------------------
# trajectories


def _polyline(
    points: np.ndarray, speed: float, dt: float, duration: float
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) at constant speed along ``points`` and the course (compass, rad) of each
    sample."""
    seg = np.diff(points, axis=0)
    L = np.hypot(seg[:, 0], seg[:, 1])
    s_cum = np.concatenate([[0.0], np.cumsum(L)])
    t = np.arange(0.0, min(duration, s_cum[-1] / speed), dt)
    s = t * speed
    k = np.clip(np.searchsorted(s_cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = (s - s_cum[k]) / L[k]
    xy = points[k] + frac[:, None] * seg[k]
    course = np.arctan2(seg[k, 0], seg[k, 1]) % (2 * np.pi)  # clockwise from north
    return xy, course


def trajectory(
    kind: str,
    rng: np.random.Generator,
    dt: float,
    duration: float,
    centre=(180.0, 180.0),
    passes: int = 5,
) -> dict[str, np.ndarray]:
    """A lawnmower (rows east-west), an outward spiral over a 360 m square, or a star of ``passes``
    straight passes crossing at ``centre``, at 20-35 m; yaw = course; AR(1) roll/pitch.  Low and
    wide enough that the legs (dep_b < 10 deg) act beyond ~110-200 m."""
    h = float(rng.uniform(20.0, 35.0))
    if kind == "lawnmower":
        sp = float(rng.uniform(28.0, 40.0))
        ys = np.arange(0.0, 360.0 + 1e-9, sp)
        pts = []
        for j, y in enumerate(ys):
            xs = (0.0, 360.0) if j % 2 == 0 else (360.0, 0.0)
            pts += [(xs[0], y), (xs[1], y)]
        points = np.array(pts)
    # straight 300 m passes crossing at ``centre``, headings spread over 180 deg
    elif kind == "star":
        c = np.asarray(centre, dtype=float)[:2]
        th0 = float(rng.uniform(0.0, np.pi))
        # a lead-in leg, so that the passes fall in random chunks
        lead = float(rng.uniform(0.0, 150.0))
        pts = []
        for j in range(passes):
            u = np.array([np.sin(th0 + j * np.pi / passes), np.cos(th0 + j * np.pi / passes)])
            a, b = (c - 150.0 * u, c + 150.0 * u) if j % 2 == 0 else (c + 150.0 * u, c - 150.0 * u)
            if j == 0:
                pts.append(a + lead * np.array([-u[1], u[0]]))
            pts += [tuple(a), tuple(b)]
        points = np.array(pts, dtype=float)
    else:
        th = np.linspace(0.0, 4 * 2 * np.pi, 600)
        r = 15.0 + 165.0 * th / th[-1]
        points = np.column_stack([180.0 + r * np.sin(th), 180.0 + r * np.cos(th)])
    xy, course = _polyline(points, 5.0, dt, duration)
    n = len(xy)
    phi = np.exp(-dt / 0.5)
    rp = np.zeros((n, 2))
    e = rng.normal(0.0, np.deg2rad(3.0) * np.sqrt(1 - phi * phi), size=(n, 2))
    for i in range(1, n):
        rp[i] = phi * rp[i - 1] + e[i]
    # cruising: nose 4 deg down
    att = np.column_stack([rp[:, 0], rp[:, 1] - np.deg2rad(4.0), course])
    t = np.arange(n) * dt
    pos = np.column_stack([xy, np.full(n, h) + rng.normal(0.0, 0.3, n)])
    return {"t": t, "pos": pos, "att": att}


# ---------------------------------------------------------------------------------------------
# channel


def body_los(
    tx: np.ndarray, pos: np.ndarray, att: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body-frame unit LOS (FRD) from the UAV to ``tx`` (ENU point or (N, 3)): u_b = R_nb^T u_ned,
    R_nb = Rz(yaw) Ry(pitch) Rx(roll) (SPEC section 1), written out."""
    d = np.broadcast_to(tx, pos.shape) - pos
    u = np.column_stack([d[:, 1], d[:, 0], -d[:, 2]])  # NED
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r, p, y = att[:, 0], att[:, 1], att[:, 2]
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    # rows of R_nb^T = columns of R_nb
    bx = (cy * cp) * u[:, 0] + (sy * cp) * u[:, 1] - sp * u[:, 2]
    by = (
        (cy * sp * sr - sy * cr) * u[:, 0]
        + (sy * sp * sr + cy * cr) * u[:, 1]
        + (cp * sr) * u[:, 2]
    )
    bz = (
        (cy * sp * cr + sy * sr) * u[:, 0]
        + (sy * sp * cr - cy * sr) * u[:, 1]
        + (cp * cr) * u[:, 2]
    )
    return bx, by, bz


def dipole_db(sin_el: np.ndarray) -> np.ndarray:
    """Vertical half-wave dipole, G = 1.641 (cos(pi/2 sin el) / cos el)^2 (SPEC section 3), floored
    at -40 dBi."""
    cos_el = np.sqrt(np.maximum(1.0 - sin_el**2, 1e-12))
    g = 1.641 * (np.cos(0.5 * np.pi * sin_el) / cos_el) ** 2
    return 10 * np.log10(np.maximum(g, 1e-4))


def gamma_v(sin_psi: np.ndarray, eps_r: float, sigma: float) -> np.ndarray:
    """Fresnel reflection coefficient, vertical polarisation, eps = eps_r - j sigma / (omega
    eps0)."""
    eps = eps_r - 1j * sigma / (2 * np.pi * FC_HZ * EPS0)
    root = np.sqrt(eps - (1 - sin_psi**2) + 0j)
    return (eps * sin_psi - root) / (eps * sin_psi + root)


def channel_db(
    tx: np.ndarray,
    pos: np.ndarray,
    att: np.ndarray,
    eps_r: float = 2.0,
    sigma: float = 0.0,
    rx_extra_db=None,
    tx_extra_db=None,
) -> np.ndarray:
    """Two-ray (eq. 1) with per-ray dipole gains; the UAV's at body-frame angles, the rover's
    upright.

    ``rx_extra_db(az_b, dep_b)`` / ``tx_extra_db(az_world)``: extra antenna gain (dB) on both rays.
    """
    d_vec = tx - pos
    d_h = np.hypot(d_vec[:, 0], d_vec[:, 1])
    h_r, h_t = pos[:, 2], tx[2]
    d_los = np.sqrt(d_h**2 + (h_r - h_t) ** 2)
    d_ref = np.sqrt(d_h**2 + (h_r + h_t) ** 2)
    sin_psi = (h_r + h_t) / d_ref
    image = np.array([tx[0], tx[1], -tx[2]])
    bx, by, bz = body_los(tx, pos, att)
    bx2, by2, bz2 = body_los(image, pos, att)
    g_r1, g_r2 = dipole_db(bz), dipole_db(bz2)  # el = -dep_b; the dipole is symmetric
    g_t1 = dipole_db((h_r - h_t) / d_los)
    g_t2 = dipole_db(sin_psi)
    if rx_extra_db is not None:
        g_r1 = g_r1 + rx_extra_db(np.arctan2(by, bx) % (2 * np.pi), np.arcsin(np.clip(bz, -1, 1)))
        g_r2 = g_r2 + rx_extra_db(
            np.arctan2(by2, bx2) % (2 * np.pi), np.arcsin(np.clip(bz2, -1, 1))
        )
    if tx_extra_db is not None:
        az_w = np.arctan2(-d_vec[:, 0], -d_vec[:, 1]) % (2 * np.pi)
        g_t1, g_t2 = g_t1 + tx_extra_db(az_w), g_t2 + tx_extra_db(az_w)
    a1 = 10 ** ((g_r1 + g_t1) / 20) / d_los
    a2 = 10 ** ((g_r2 + g_t2) / 20) / d_ref
    field = a1 + gamma_v(sin_psi, eps_r, sigma) * a2 * np.exp(
        -1j * 2 * np.pi * (d_ref - d_los) / LAMBDA_M
    )
    return PT_DBM + 20 * np.log10(LAMBDA_M / (4 * np.pi)) + 20 * np.log10(np.abs(field))


def leg_loss_db(
    tx: np.ndarray,
    pos: np.ndarray,
    att: np.ndarray,
    beta: float,
    half_width_deg: float = 5.0,
    threshold_deg: float = 10.0,
    legs_deg: tuple[float, ...] = LEGS_DEG,
) -> np.ndarray:
    """-Upsilon = -10 beta log10(d_los) where a leg blocks the LOS (paper eqs. 8-9)."""
    bx, by, bz = body_los(tx, pos, att)
    az = np.rad2deg(np.arctan2(by, bx)) % 360.0
    dep = np.rad2deg(np.arcsin(np.clip(bz, -1, 1)))
    near = np.zeros(len(az), bool)
    for leg in legs_deg:
        near |= np.abs((az - leg + 180.0) % 360.0 - 180.0) <= half_width_deg
    s = near & (dep < threshold_deg)
    d_los = np.linalg.norm(tx - pos, axis=1)
    return -10.0 * beta * np.log10(d_los) * s


def exp_field(rng: np.random.Generator, sigma: float, L: float, m: int = 500):
    """Exponential-covariance Gaussian field by random Fourier features (Cauchy spectrum)."""
    w = rng.normal(size=(m, 2)) / (L * np.sqrt(rng.chisquare(1.0, size=(m, 1))))
    b = rng.uniform(0, 2 * np.pi, m)
    return lambda xy: sigma * np.sqrt(2.0 / m) * np.cos(xy @ w.T + b).sum(axis=1)


# ------------------------------------------------------------------------------------------------
# cases


def make_case(
    effect: str,
    seed: int,
    n_flights: int = 2,
    dt: float = 0.25,
    duration: float = 420.0,
    noise_db: float = 1.0,
    strength: float = 1.0,
    passes: int = 5,
) -> tuple[list[dict], dict]:
    """Flights (dicts of t, pos, att, rss, tx) with ``effect`` withheld from the base, and the
    truth.

    ``strength`` scales the withheld effect's size (beta, amplitudes, depths, sigma, tau; the
    ground's permittivity departs from the base's 2 by that factor); ``passes``: the star's passes
    (``nadir_over``)."""
    rng = np.random.default_rng(seed)
    truth: dict = {"effect": effect, "strength": strength}
    k_s = strength
    if effect == "shadowing":
        truth.update(sigma_db=4.0 * k_s, corr_len_m=float(rng.uniform(30.0, 60.0)))
    phi = float(rng.uniform(0.0, 2 * np.pi))
    flights = []
    for k in range(n_flights):
        if effect == "nadir_over":  # the rover first, then passes right over it
            tx = np.array([rng.uniform(120.0, 240.0), rng.uniform(120.0, 240.0), TX_HEIGHT_M])
            tr = trajectory("star", rng, dt, duration, centre=tx, passes=passes)
        else:
            tr = trajectory(("lawnmower", "spiral")[k % 2], rng, dt, duration)
            # legs: rover near a corner (long range)
            lo, hi = (20.0, 90.0) if effect == "legs" else (60.0, 300.0)
            # mid-way along an edge: the legs act only over the far half of the field
            if effect == "legs_far":
                lo, hi = 100.0, 260.0
            if effect == "nadir":  # under a lawnmower row, so that the flights pass over the rover
                lo, hi = 120.0, 240.0
            tx = np.array([rng.uniform(lo, hi), rng.uniform(lo, hi), TX_HEIGHT_M])
            if effect == "legs_far":
                edge = float(rng.uniform(20.0, 60.0))
                tx[int(rng.integers(0, 2))] = edge if rng.uniform() < 0.5 else 360.0 - edge
        t, pos, att = tr["t"], tr["pos"], tr["att"]
        kw: dict = {}
        if effect == "ground":
            truth.update(
                eps_r=truth.get("eps_r", 2.0 + k_s * (float(rng.uniform(10.0, 25.0)) - 2.0)),
                sigma_s_m=0.005,
            )
            kw = {"eps_r": truth["eps_r"], "sigma": 0.005}
        elif effect == "ripple":
            truth.setdefault("amp_db", k_s * float(rng.uniform(2.0, 2.5)))
            truth["phase_deg"] = np.rad2deg(phi)
            kw = {"rx_extra_db": lambda az, dep, phi=phi: truth["amp_db"] * np.cos(3 * (az - phi))}
        elif effect == "notch":
            # centred where the flights see the rover (else nothing could see it)
            if "azimuth_deg" not in truth:
                bx, by, _ = body_los(tx, pos, att)
                az_seen = np.arctan2(by, bx) % (2 * np.pi)
                phi = float(az_seen[rng.integers(0, len(az_seen))])
                truth.update(
                    depth_db=10.0 * k_s, azimuth_deg=float(np.rad2deg(phi)), width_deg=15.0
                )
            kw = {
                "rx_extra_db": lambda az, dep, phi=phi: (
                    -10.0
                    * k_s
                    * np.exp(-0.5 * ((np.angle(np.exp(1j * (az - phi)))) / np.deg2rad(15.0)) ** 2)
                )
            }
        elif effect == "tx_azimuth":
            truth.update(amp_db=3.0 * k_s, azimuth_deg=float(np.rad2deg(phi)))
            kw = {"tx_extra_db": lambda az, phi=phi: 3.0 * k_s * np.cos(az - phi)}
        # airframe, payload below the antenna: steep depression, any az
        elif effect in (
            "nadir",
            "nadir_over",
        ):
            truth.update(depth_db=8.0 * k_s, centre_deg=75.0, width_deg=8.0)
            kw = {
                "rx_extra_db": lambda az, dep: (
                    -8.0 * k_s * np.exp(-0.5 * ((np.rad2deg(dep) - 75.0) / 8.0) ** 2)
                )
            }
        q_pos, q_att = pos, att
        if effect == "timing":
            truth.setdefault("tau_s", k_s * float(rng.uniform(0.5, 1.0)))
            tq = t - truth["tau_s"]  # received where the UAV was tau earlier
            q_pos = np.column_stack([np.interp(tq, t, pos[:, j]) for j in range(3)])
            yaw = np.unwrap(att[:, 2])
            q_att = np.column_stack(
                [
                    np.interp(tq, t, att[:, 0]),
                    np.interp(tq, t, att[:, 1]),
                    np.interp(tq, t, yaw) % (2 * np.pi),
                ]
            )
        p = channel_db(tx, q_pos, q_att, **kw)
        if effect in ("legs", "legs_far"):
            truth.setdefault("beta", k_s * float(rng.uniform(0.5, 0.7)))
            truth["threshold_deg"] = 10.0 if effect == "legs" else 8.0
            truth["legs_deg"] = LEGS_DEG if effect == "legs" else QUAD_LEGS_DEG
            p = p + leg_loss_db(
                tx,
                q_pos,
                q_att,
                truth["beta"],
                threshold_deg=truth["threshold_deg"],
                legs_deg=truth["legs_deg"],
                half_width_deg=5.0 if effect == "legs" else 7.0,
            )
        phase = None
        if effect == "drift":  # a receiver warming up: its gain settles over a couple of minutes
            amp = k_s * float(rng.uniform(3.0, 4.0)) * float(rng.choice([-1.0, 1.0]))
            truth.setdefault("amp_db", []).append(amp)
            p = p + amp * (1.0 - np.exp(-t / 120.0))
        # a gain step at an event the log shows: a turn, or a logged phase change
        elif effect == "step":
            n = len(t)
            turns = (
                np.nonzero(np.abs(np.angle(np.exp(1j * np.diff(att[:, 2])))) > np.deg2rad(90.0))[0]
                + 1
            )
            mid = turns[(turns > n // 4) & (turns < 3 * n // 4)]
            i_step = (
                int(rng.choice(mid))
                if len(mid) and k % 2 == 0
                else int(rng.integers(n // 4, 3 * n // 4))
            )
            # no sharp turn there (the spiral): the log records the switch
            if not (len(mid) and k % 2 == 0):
                phase = np.where(np.arange(n) < i_step, "mission", "adaptive")
            amp = k_s * float(rng.uniform(2.5, 3.0)) * float(rng.choice([-1.0, 1.0]))
            truth.setdefault("amp_db", []).append(amp)
            truth.setdefault("step_s", []).append(float(t[i_step]))
            p = p + amp * (np.arange(n) >= i_step)
        # fixed over the ground; a fresh field per flight (another rover position)
        if effect == "shadowing":
            p = p + exp_field(rng, truth["sigma_db"], truth["corr_len_m"])(pos[:, :2])
        rss = p + float(rng.uniform(-60.0, 20.0)) + rng.normal(0.0, noise_db, len(p))
        flights.append({"t": t, "pos": pos, "att": att, "rss": rss, "tx": tx, "phase": phase})
    return flights, truth


def diagnose_case(effect: str, seed: int, **kw) -> dict:
    """Generate one case and run the diagnosis (``mission.gap.structure.identify``) on it."""
    raw, truth = make_case(effect, seed, **kw)
    flights = [
        FlightSamples(
            name=f"synth{k}",
            t_s=f["t"],
            enu_m=f["pos"],
            attitude_rad=f["att"],
            rss_dbm=f["rss"],
            tx_enu_m=f["tx"],
            phase=f.get("phase"),
        )
        for k, f in enumerate(raw)
    ]
    base = Pipeline(make_model("two-ray", pattern="dipole").with_effect(Attitude()))
    cfg = FitConfig(seed=seed, fit_max_samples=1200, workers=1)

    out = identify(flights, base, list(library().values()), cfg)
    out.update(
        effect=effect,
        seed=seed,
        truth=truth,
        expected=EXPECTED[effect],
        hit=out["named"] == EXPECTED[effect],
    )

    res = [offset_residual(f.rss_dbm, base.predict(f), False, "l2") for f in flights]
    m = sum(c.applicable(base) for c in usable_candidates(list(library().values()), flights))
    out["near_nadir"] = power_statement(
        [np.rad2deg(align(f).dep_b) for f in flights],
        res,
        [block_length(r) for r in res],
        make_folds(flights, cfg),
        cfg,
        m,
        loss_db=truth.get("depth_db", 3.0),
        seed=seed,
    )

    out["time_power"] = time_power_statement(
        flights, res, make_folds(flights, cfg), cfg, m, cfg.split, seed=seed
    )
    return out
