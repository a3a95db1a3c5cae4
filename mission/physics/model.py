"""``PropagationModel``: a tuple of named effects (``mission.physics.effects``) evaluated as one
RSS.

``rss_dbm`` is the fast path (float32 by default, chunked, algebra instead of trig where possible);
``explain`` is a float64 reference written with explicit angles, used by the tests to check the fast
path. Without ``attitude`` the body frame is level with yaw 0 (plain two-ray); with zero attitude
the enhanced two-ray model equals two-ray (+ shadowing) exactly.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

from mission.physics.constants import friis_constant_db, wavelength
from mission.physics.effects import TWO_PI, FreeSpace, GroundReflection, Link, RxAntenna, TxAntenna
from mission.physics.geometry import (
    as_attitude,
    bearing,
    body_angles,
    body_azimuth,
    body_from_enu_matrix,
    body_from_enu_planes,
    elevation,
    enu_to_ned,
    horizontal_distance,
    link_delta,
)

# elements per block: float32 temporaries of 32 KiB stay in L2 and below glibc's mmap threshold
CHUNK = 8192


@dataclass(frozen=True)
class AttitudePlanes:
    """The body-from-ENU rotation planes (3, 3, N) of one attitude series under one model's attitude
    effect, in the model's dtype: made once by ``PropagationModel.attitude_planes`` and handed back
    to ``rss_dbm`` by a caller that evaluates the same samples many times (the gap fits), instead of
    a cache inside the model."""

    effect: Any
    dtype: str
    planes: NDArray


TERMS_KEPT = 16  # additive terms a PreparedLinks keeps per block (least recently used dropped)


@dataclass(frozen=True, eq=False)
class PreparedLinks:
    """N links, each sample with its own transmitter, made ready once for the many ``rss_dbm`` calls
    of a fit (models that differ in their effects' parameters but share the attitude effect and the
    dtype): the centred inputs in the model's dtype and the rotation planes, block by block; each
    block's geometry and the additive terms (``rss_term_db``) of the effects evaluated on it are
    kept as first computed (read-only; the ``TERMS_KEPT`` most recent terms per block).  Made by
    ``PropagationModel.prepare_links`` and owned by the caller (the gap fits' ``Selection``), not
    cached inside the model; the RSS is that of ``rss_dbm`` on the same inputs, bit for bit."""

    attitude: Any  # the attitude effect the planes were made under (None: level body frame)
    dtype: str
    n: int
    spans: tuple[tuple[int, int], ...]  # (first, end) sample of each block
    tx: tuple[NDArray, ...]  # per block (1, nb, 3), centred, model dtype
    rx: tuple[NDArray, ...]  # per block (nb, 3)
    planes: tuple[NDArray | None, ...]  # per block (3, 3, nb) or None
    geometry: list[tuple | None] = field(default_factory=list)  # per block, once computed
    terms: list[OrderedDict] = field(default_factory=list)  # per block: (effect, what) -> array

    def kept(self, b: int, key: Any, compute: Callable[[], Any]) -> Any:
        """``compute()`` on block ``b`` (an effect's term or antenna amplitude: a function of the
        effect in ``key`` and the block's geometry only), kept; an unhashable key: made afresh."""
        kept = self.terms[b]
        try:
            hit = kept.get(key)
        except TypeError:
            return compute()
        if hit is None:
            hit = compute()
            if isinstance(hit, np.ndarray):
                hit.flags.writeable = False
            kept[key] = hit
            if len(kept) > TERMS_KEPT:
                kept.popitem(last=False)
        else:
            kept.move_to_end(key)
        return hit


@dataclass(frozen=True)
class PropagationModel:
    """A propagation model = a tuple of named effects; see ``mission.physics.propagation`` for the
    effects."""

    effects: tuple[Any, ...]
    name: str = "custom"
    dtype: DTypeLike = np.float32
    chunk: int = CHUNK

    def __post_init__(self) -> None:
        names = [e.name for e in self.effects]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate effect names in {names}")
        if "free_space" not in names:
            raise ValueError("a model needs the 'free_space' effect (transmit power, carrier)")
        object.__setattr__(self, "_names", tuple(names))  # the effects are frozen: made once

    # -- composition
    @property
    def names(self) -> tuple[str, ...]:
        return self._names

    def effect(self, name: str) -> Any:
        """The effect called ``name``; KeyError if absent."""
        for e in self.effects:
            if e.name == name:
                return e
        raise KeyError(f"no effect {name!r} in model {self.name!r} (has {', '.join(self.names)})")

    def has(self, name: str) -> bool:
        return name in self.names

    def without(self, name: str) -> PropagationModel:
        """The model with effect ``name`` removed (KeyError if absent)."""
        self.effect(name)
        return replace(self, effects=tuple(e for e in self.effects if e.name != name))

    def with_effect(self, effect: Any) -> PropagationModel:
        """The model with ``effect`` replacing the effect of the same name, or appended."""
        if self.has(effect.name):
            return replace(
                self, effects=tuple(effect if e.name == effect.name else e for e in self.effects)
            )
        return replace(self, effects=self.effects + (effect,))

    def with_params(self, name: str, **params: Any) -> PropagationModel:
        """The model with effect ``name``'s dataclass fields changed, e.g.
        ``with_params("leg_shadowing", beta=3.1)``."""
        return self.with_effect(replace(self.effect(name), **params))

    def _get(self, name: str) -> Any:
        return self.effect(name) if self.has(name) else None

    # -- fast path
    def attitude_planes(self, attitude_rad: ArrayLike, n: int | None = None) -> AttitudePlanes:
        """The rotation planes of ``attitude_rad`` ((N, 3) rad, or one attitude for ``n`` samples)
        under this model's attitude effect, read-only, for ``rss_dbm(..., planes=)``."""
        dt = np.dtype(self.dtype)
        a = np.asarray(attitude_rad, dtype=float)
        att = as_attitude(a, n if n is not None else len(a) if a.ndim == 2 else 1)
        C = body_from_enu_planes(self.effect("attitude").apply(att), dt)
        C.flags.writeable = False
        return AttitudePlanes(self.effect("attitude"), dt.str, C)

    def prepare_links(
        self,
        tx_enu: ArrayLike,
        rx_enu: ArrayLike,
        attitude_rad: ArrayLike | None = None,
        centre: ArrayLike | None = None,
    ) -> PreparedLinks:
        """``PreparedLinks`` of tx (N, 3) paired with rx (N, 3) (attitude, ``centre`` as for
        ``rss_dbm``) under this model's attitude effect and dtype, for ``rss_dbm(links=)``."""
        dt = np.dtype(self.dtype)
        tx, rx, _, paired = _prepare(tx_enu, rx_enu)
        N = rx.shape[0]
        if not paired and N > 1:
            raise ValueError("prepared links pair each sample with its own transmitter, tx (N, 3)")
        rxc, txc = _centred(tx, rx, centre, dt)
        att = self.effect("attitude") if self.has("attitude") and attitude_rad is not None else None
        C = None
        if att is not None:
            C = body_from_enu_planes(att.apply(as_attitude(attitude_rad, N)), dt)
        nb = min(N, self.chunk) if N else 1
        spans = tuple((n0, min(N, n0 + nb)) for n0 in range(0, N, nb))
        arrays = [
            (
                txc[:, n0:n1].astype(dt),
                rxc[n0:n1],
                None if C is None else C[:, :, n0:n1],
            )
            for n0, n1 in spans
        ]
        for a in arrays:
            for v in a:
                if v is not None:
                    v.flags.writeable = False
        return PreparedLinks(
            att,
            dt.str,
            N,
            spans,
            tuple(a[0] for a in arrays),
            tuple(a[1] for a in arrays),
            tuple(a[2] for a in arrays),
            [None] * len(spans),
            [OrderedDict() for _ in spans],
        )

    def rss_dbm(
        self,
        tx_enu: ArrayLike,
        rx_enu: ArrayLike,
        attitude_rad: ArrayLike | None = None,
        centre: ArrayLike | None = None,
        planes: AttitudePlanes | None = None,
        links: PreparedLinks | None = None,
    ) -> NDArray:
        """RSS (dBm): tx (..., 3) broadcast against rx (N, 3) -> (...broadcast..., N); attitude (N,
        3) rad.

        tx (3,) or (M, 1, 3) gives (N,) or (M, N) (every transmitter x every sample); tx (N, 3)
        pairs with the samples one to one.  ``centre`` (N, 3), z = 0: each sample's shift instead of
        the samples' mean, so that several flights evaluated in one call (paired tx) keep their own
        centre and get the very values of one call per flight (the per-call overhead dominates on
        small fits).  ``planes``: the attitude's rotation planes from ``attitude_planes`` (this
        model's, these samples'), used instead of ``attitude_rad``.  ``links``: the samples made
        ready by ``prepare_links`` (this model's attitude effect and dtype), used instead of every
        other argument.
        """
        dt = np.dtype(self.dtype)
        if links is not None:
            att = self.effect("attitude") if self.has("attitude") else None
            if links.dtype != dt.str or (links.attitude is not None and links.attitude != att):
                raise ValueError("links were prepared for another model's attitude effect or dtype")
            if att is not None and links.attitude is None:
                raise ValueError("links were prepared without the attitude this model needs")
            out = np.empty((1, links.n), dtype=dt)
            for b, (n0, n1) in enumerate(links.spans):
                out[:, n0:n1] = self._block(links.tx[b], links.rx[b], links.planes[b], links, b)
            return out.reshape(links.n)
        tx, rx, out_shape, paired = _prepare(tx_enu, rx_enu)
        N = rx.shape[0]
        # shift x, y to the samples' centre so float32 keeps millimetres
        if centre is not None and not paired and N > 1:
            raise ValueError("centre needs tx paired with the samples, shape (N, 3)")
        rxc, txc = _centred(tx, rx, centre, dt)
        C = None
        if self.has("attitude") and planes is not None:
            if (
                planes.effect != self.effect("attitude")
                or planes.dtype != dt.str
                or planes.planes.shape[-1] != N
            ):
                raise ValueError(
                    "planes were made for another model's attitude effect, dtype or samples"
                )
            C = planes.planes
        elif self.has("attitude") and attitude_rad is not None:
            # u_b = C delta; stored (3, 3, N) so that C[i, j] is contiguous over the samples
            C = body_from_enu_planes(
                self.effect("attitude").apply(as_attitude(attitude_rad, N)), dt
            )
        K = txc.shape[0]
        out = np.empty((K, N), dtype=dt)
        nb = min(N, self.chunk) if N else 1
        mb = max(1, self.chunk // max(nb, 1))
        for n0 in range(0, N, nb):
            n1 = min(N, n0 + nb)
            Cb = None if C is None else C[:, :, n0:n1]
            for k0 in range(0, K, mb):
                k1 = min(K, k0 + mb)
                tb = txc[k0:k1, n0:n1] if paired else txc[k0:k1]
                out[k0:k1, n0:n1] = self._block(tb.astype(dt), rxc[n0:n1], Cb)
        return out.reshape(out_shape)

    def _block(
        self,
        tx: NDArray,
        rx: NDArray,
        C: NDArray | None,
        links: PreparedLinks | None = None,
        b: int = 0,
    ) -> NDArray:
        """RSS of one block: tx (mb, 1 or nb, 3), rx (nb, 3), C (3, 3, nb) or None -> (mb, nb);
        ``links``: its block ``b`` keeps the geometry and the additive terms.  Four phases: the
        link geometry, the direct ray's antenna amplitude, the two-ray power with the ground, the
        power in dBm with the additive terms."""
        geo = links.geometry[b] if links is not None else None
        if geo is None:
            geo = _link_geometry(tx, rx, C)
            if links is not None:
                for v in geo[2:9] + tuple(geo[9]):
                    v.flags.writeable = False
                links.geometry[b] = geo

        def kept(key: Any, compute: Callable[[], Any]) -> Any:  # an amplitude, kept by the links
            return compute() if links is None else links.kept(b, key, compute)

        # compass bearing TX -> UAV, shared by both rays, computed at most once
        az_tx = _once(lambda: bearing(-geo[2], -geo[3]))
        dt = tx.dtype.type
        amp_dir = self._direct_amplitude(geo, C, kept, az_tx, dt)
        F2, d_ref = self._two_ray_power(geo, C, amp_dir, kept, az_tx, dt)
        return self._power_dbm(F2, geo, d_ref, kept, dt)

    def _direct_amplitude(self, geo: tuple, C: NDArray | None, kept, az_tx, dt) -> NDArray:
        """sqrt(G_t G_r) / d_los of the direct ray (the antennas' amplitudes, kept by the links)."""
        z_t, z_r, dx, dy, dz, d2, d_los, inv_los, d, u_b = geo
        ta: TxAntenna | None = self._get("tx_antenna")
        ra: RxAntenna | None = self._get("rx_antenna")
        amp_dir = inv_los  # sqrt(G_t G_r) / d_los
        # departure towards the UAV: sin el = (h_r - h_t) / d_los, cos el = d / d_los
        if ta is not None:
            amp_dir = amp_dir * kept(
                (ta, "direct"), lambda: ta._amplitude(-dz * inv_los, d * inv_los, az_tx)
            )
        if ra is not None:  # arrival: el = -dep_b = -u_b.z / |u|

            def rx_direct() -> NDArray:
                s_r = -u_b[2] * inv_los
                c_r = (
                    d * inv_los if C is None else np.sqrt(np.maximum(dt(1.0) - s_r * s_r, dt(0.0)))
                )
                return ra._amplitude(s_r, c_r, lambda: body_azimuth(u_b[0], u_b[1]))

            amp_dir = amp_dir * kept((ra, "direct"), rx_direct)
        return amp_dir

    def _two_ray_power(
        self, geo: tuple, C: NDArray | None, amp_dir: NDArray, kept, az_tx, dt
    ) -> tuple[NDArray, NDArray]:
        """(F^2, d_ref): the power factor of the direct ray and, with a ground, its reflection
        (eq. 1), and the reflected path length (d_los without a ground)."""
        z_t, z_r, dx, dy, dz, d2, d_los, inv_los, d, u_b = geo
        gr: GroundReflection | None = self._get("ground_reflection")
        if gr is None:
            return amp_dir * amp_dir, d_los
        fs: FreeSpace = self.effect("free_space")
        ta: TxAntenna | None = self._get("tx_antenna")
        ra: RxAntenna | None = self._get("rx_antenna")
        h_s = z_t + z_r
        d_ref = np.sqrt(d2 + h_s * h_s)  # d_ref = sqrt(d^2 + (h_r + h_t)^2)
        inv_ref = dt(1.0) / d_ref
        sin_psi = h_s * inv_ref  # grazing angle psi
        amp_ref = inv_ref
        if ta is not None:  # departs downwards towards the specular point
            amp_ref = amp_ref * kept(
                (ta, "reflected"), lambda: ta._amplitude(-sin_psi, d * inv_ref, az_tx)
            )
        if ra is not None:  # arrives from the image source at (x_t, y_t, -h_t)
            if C is None:
                s_r2, c_r2 = -sin_psi, d * inv_ref

                def az2() -> NDArray:
                    return bearing(dx, dy)
            else:
                two_zt = z_t + z_t
                ub2 = tuple(u_b[i] - C[i, 2] * two_zt for i in range(3))
                s_r2 = -ub2[2] * inv_ref
                c_r2 = np.sqrt(np.maximum(dt(1.0) - s_r2 * s_r2, dt(0.0)))

                def az2() -> NDArray:
                    return body_azimuth(ub2[0], ub2[1])

            amp_ref = amp_ref * kept((ra, "reflected"), lambda: ra._amplitude(s_r2, c_r2, az2))
        g_re, g_im = gr._gamma_fast(sin_psi, d2 * inv_ref * inv_ref, fs.fc_hz)
        # RF phase difference psi_phase (eq. 1) = k (d_ref - d_los) = k 4 h_t h_r / (d_ref +
        # d_los): no cancellation
        dphi = (z_t * z_r) * dt(4.0 * TWO_PI / wavelength(fs.fc_hz)) / (d_ref + d_los)
        # (eq. 1) |A + Gamma B e^{-j dphi}|^2
        #         = A^2 + |Gamma|^2 B^2 + 2 A B Re(Gamma e^{-j dphi})
        re = g_re * np.cos(dphi)
        if g_im is not None:
            re += g_im * np.sin(dphi)
            g2 = g_re * g_re + g_im * g_im
        else:
            g2 = g_re * g_re
        AB = amp_dir * amp_ref
        F2 = amp_dir * amp_dir + g2 * amp_ref * amp_ref + dt(2.0) * AB * re
        np.maximum(F2, dt(1e-30), out=F2)
        return F2, d_ref

    def _power_dbm(self, F2: NDArray, geo: tuple, d_ref: NDArray, kept, dt) -> NDArray:
        """10 log10(F^2) + P_t + the Friis constant, plus the effects' additive terms."""
        z_t, z_r, dx, dy, dz, d2, d_los, inv_los, d, u_b = geo
        fs: FreeSpace = self.effect("free_space")
        grounded = self._get("ground_reflection") is not None
        rss = np.log(F2)  # float32 log is ~5x faster than log10
        rss *= dt(10.0 / math.log(10.0))
        rss += dt(fs.pt_dbm + friis_constant_db(fs.fc_hz))  # P_t + 20 log10(lambda / 4 pi)
        extra = [e for e in self.effects if hasattr(e, "rss_term_db")]
        if extra:
            link = Link((dx, dy, dz), z_t, z_r, d_los, d_ref, u_b)
            for e in extra:
                rss += kept((e, "term", grounded), lambda e=e: e.rss_term_db(link))
        return rss

    # -- reference / explanation
    def explain(
        self, tx_enu: ArrayLike, rx_enu: ArrayLike, attitude_rad: ArrayLike | None = None
    ) -> dict[str, NDArray]:
        """Every intermediate quantity (float64 reference, explicit angles) of the broadcast shape.

        Keys: d_2d, d_los, d_ref, h_t, h_r, grazing_rad, gamma_abs, gamma_phase_rad (arg Gamma),
        phase_diff_rad (the paper's RF phase difference psi_phase, eq. 1), el_tx_dir_rad,
        el_tx_ref_rad, az_tx_rad, g_tx_dir_dbi, g_tx_ref_dbi, g_rx_dir_dbi, g_rx_ref_dbi, az_b_rad,
        dep_b_rad, az_b_ref_rad, dep_b_ref_rad, direct_dbm, reflected_dbm, two_ray_dbm, shadowed,
        upsilon_db, rss_dbm (and ``<name>_db`` for other additive effects).  Phases: the geometry
        and angles, the antenna gains, the two rays (eq. 1), the additive terms.
        """
        tx, rx, out_shape, paired = _prepare(tx_enu, rx_enu)
        N = rx.shape[0]
        T = tx if paired else np.broadcast_to(tx, (tx.shape[0], N, 3))
        att = as_attitude(attitude_rad if self.has("attitude") else None, N)
        if self.has("attitude"):
            att = self.effect("attitude").apply(att)
        u = T - rx  # p_tx - p_uav, ENU
        q = _explain_geometry(T, u, rx, att)
        q.update(self._explain_gains(q))
        q.update(self._explain_rays(q))
        terms = self._explain_terms(q, u, att, N)
        q["rss_dbm"] = q["two_ray_dbm"] - q["upsilon_db"]
        for term in terms.values():
            q["rss_dbm"] = q["rss_dbm"] + term
        q.update(terms)
        head = ["direct_dbm", "reflected_dbm", *terms]  # the keys' order as it always was
        res = {key: q[key] for key in head + [k for k in _EXPLAIN_KEYS if k not in head]}
        return {key: np.asarray(v).reshape(out_shape) for key, v in res.items()}

    def _explain_gains(self, q: dict) -> dict[str, NDArray]:
        """The antennas' gains (dBi) on the direct and reflected rays (0 without the antenna)."""
        ta, ra = self._get("tx_antenna"), self._get("rx_antenna")
        zero = np.zeros_like(q["d_los"])
        return {
            "g_tx_dir_dbi": ta.gain_dbi(q["el_tx_dir_rad"], q["az_tx_rad"]) if ta else zero,
            "g_tx_ref_dbi": ta.gain_dbi(q["el_tx_ref_rad"], q["az_tx_rad"]) if ta else zero,
            "g_rx_dir_dbi": ra.gain_dbi(-q["dep_b_rad"], q["az_b_rad"]) if ra else zero,
            "g_rx_ref_dbi": ra.gain_dbi(-q["dep_b_ref_rad"], q["az_b_ref_rad"]) if ra else zero,
        }

    def _explain_rays(self, q: dict) -> dict[str, NDArray]:
        """The direct and reflected fields (eq. 1) as powers, their sum, and Gamma."""
        fs: FreeSpace = self.effect("free_space")
        gr = self._get("ground_reflection")
        lam = wavelength(fs.fc_hz)
        d_los, d_ref, psi = q["d_los"], q["d_ref"], q["grazing_rad"]
        k = TWO_PI / lam
        g_dir = (q["g_tx_dir_dbi"] + q["g_rx_dir_dbi"]) / 20
        E = 10**g_dir / d_los * np.exp(-1j * k * d_los)  # eq. 1, direct term
        if gr is not None:
            Gam = gr.gamma(psi, fs.fc_hz)
            g_ref = (q["g_tx_ref_dbi"] + q["g_rx_ref_dbi"]) / 20
            E_ref = Gam * 10**g_ref / d_ref * np.exp(-1j * k * d_ref)
        else:
            Gam = np.zeros_like(psi, dtype=complex)
            E_ref = np.zeros_like(E)
        const = fs.pt_dbm + 20 * np.log10(lam / (4 * np.pi))
        out = {"phase_diff_rad": k * (d_ref - d_los)}
        with np.errstate(divide="ignore"):
            out["direct_dbm"] = const + 20 * np.log10(np.abs(E))
            out["reflected_dbm"] = const + 20 * np.log10(np.abs(E_ref))
        out["two_ray_dbm"] = const + 20 * np.log10(np.maximum(np.abs(E + E_ref), 1e-15))
        out.update(gamma_abs=np.abs(Gam), gamma_phase_rad=np.angle(Gam))
        return out

    def _explain_terms(self, q: dict, u: NDArray, att: NDArray, N: int) -> dict[str, NDArray]:
        """Leg shadowing (``shadowed``, ``upsilon_db`` into ``q``) and the other additive effects'
        terms, ``{"<name>_db": dB}`` in the effects' order."""
        ls = self._get("leg_shadowing")
        d_los = q["d_los"]
        q["shadowed"] = (
            ls.shadowed(q["az_b_rad"], q["dep_b_rad"]) if ls else np.zeros(d_los.shape, bool)
        )
        q["upsilon_db"] = (
            np.where(q["shadowed"], ls.upsilon_db(d_los), 0.0) if ls else np.zeros_like(d_los)
        )
        others = [
            e for e in self.effects if hasattr(e, "rss_term_db") and e.name != "leg_shadowing"
        ]
        if not others:
            return {}
        C = body_from_enu_matrix(att if self.has("attitude") else np.zeros((N, 3)))
        ub = tuple(np.einsum("nj,...nj->...n", C[:, i, :], u) for i in range(3))
        link = Link((u[..., 0], u[..., 1], u[..., 2]), q["h_t"], q["h_r"], d_los, q["d_ref"], ub)
        return {f"{e.name}_db": np.asarray(e.rss_term_db(link), dtype=float) for e in others}


def _centred(
    tx: NDArray, rx: NDArray, centre: ArrayLike | None, dt: np.dtype
) -> tuple[NDArray, NDArray]:
    """rx in ``dt`` and tx (float64) shifted by ``centre`` (N, 3), else by the samples' mean x, y:
    float32 keeps millimetres."""
    if centre is not None:
        c = np.asarray(centre, dtype=float).reshape(rx.shape[0], 3)
    else:
        c = np.zeros(3)
        c[:2] = rx[:, :2].mean(axis=0) if rx.shape[0] else 0.0
    return (rx - c).astype(dt), tx - c


def _prepare(
    tx_enu: ArrayLike, rx_enu: ArrayLike
) -> tuple[NDArray, NDArray, tuple[int, ...], bool]:
    """tx -> (K, 1, 3) (outer) or (K, N, 3) (paired), rx -> (N, 3), the output shape and the
    mode."""
    tx = np.asarray(tx_enu, dtype=float)
    rx = np.asarray(rx_enu, dtype=float)
    if rx.ndim != 2 or rx.shape[-1] != 3:
        raise ValueError(f"rx_enu must have shape (N, 3), got {rx.shape}")
    if tx.ndim < 1 or tx.shape[-1] != 3:
        raise ValueError(f"tx_enu must have shape (..., 3), got {tx.shape}")
    N = rx.shape[0]
    lead = tx.shape[:-1]
    out_shape = np.broadcast_shapes(lead, (N,))
    if lead == () or lead[-1] == 1:
        return tx.reshape(-1, 1, 3), rx, out_shape, False
    txb = np.broadcast_to(tx, out_shape + (3,)).reshape(-1, N, 3)
    return txb, rx, out_shape, True


def _once(compute: Callable[[], Any]) -> Callable[[], Any]:
    """``compute`` run at most once: the returned function gives its first result."""
    box: list = []

    def get() -> Any:
        if not box:
            box.append(compute())
        return box[0]

    return get


def _link_geometry(tx: NDArray, rx: NDArray, C: NDArray | None) -> tuple:
    """A block's link geometry in the inputs' dtype: (z_t, z_r, dx, dy, dz, d2, d_los, inv_los, d,
    u_b), ``u_b`` the TX direction in the body frame (level, yaw 0 when ``C`` is None)."""
    dt = tx.dtype.type
    z_t = tx[..., 2]
    z_r = rx[:, 2]
    dx, dy, dz = link_delta(tx, rx)  # delta = p_tx - p_rx (ENU)
    d2 = dx * dx
    d2 += dy * dy  # d_2D^2
    d_los = np.sqrt(d2 + dz * dz)  # d_los = sqrt(d^2 + (h_r - h_t)^2)
    np.maximum(d_los, dt(1e-3), out=d_los)  # coincident points: 1 mm, not a division by 0
    inv_los = dt(1.0) / d_los
    d = np.sqrt(d2)
    if C is None:  # level body frame, yaw 0: u_b = (n, e, d)
        u_b = (dy, dx, -dz)
    else:  # u_b = C delta, C per sample (computed once, not per transmitter)
        u_b = tuple(C[i, 0] * dx + C[i, 1] * dy + C[i, 2] * dz for i in range(3))
    return (z_t, z_r, dx, dy, dz, d2, d_los, inv_los, d, u_b)


# The keys of ``PropagationModel.explain`` after the rays' and the additive effects' own
_EXPLAIN_KEYS = (
    "d_2d",
    "d_los",
    "d_ref",
    "h_t",
    "h_r",
    "grazing_rad",
    "gamma_abs",
    "gamma_phase_rad",
    "phase_diff_rad",
    "el_tx_dir_rad",
    "el_tx_ref_rad",
    "az_tx_rad",
    "g_tx_dir_dbi",
    "g_tx_ref_dbi",
    "g_rx_dir_dbi",
    "g_rx_ref_dbi",
    "az_b_rad",
    "dep_b_rad",
    "az_b_ref_rad",
    "dep_b_ref_rad",
    "two_ray_dbm",
    "shadowed",
    "upsilon_db",
    "rss_dbm",
)


def _explain_geometry(T: NDArray, u: NDArray, rx: NDArray, att: NDArray) -> dict[str, NDArray]:
    """``explain``'s geometry (float64): distances, heights, the grazing angle and the angles of
    both rays at the transmitter and in the UAV's body frame (``T``: the transmitters broadcast to
    the samples, ``u``: p_tx - p_uav, ENU)."""
    h_t, h_r = T[..., 2], np.broadcast_to(rx[:, 2], u.shape[:-1])
    d_2d = horizontal_distance(u[..., 0], u[..., 1])
    psi = elevation(h_r + h_t, d_2d)  # grazing angle: the image source's depression
    az_b, dep_b = body_angles(enu_to_ned(u), att)
    u_img = u.copy()
    u_img[..., 2] = -(h_t + h_r)  # towards the image source (x_t, y_t, -h_t)
    az_b2, dep_b2 = body_angles(enu_to_ned(u_img), att)
    return {
        "d_2d": d_2d,
        "d_los": np.sqrt(d_2d**2 + (h_r - h_t) ** 2),
        "d_ref": np.sqrt(d_2d**2 + (h_r + h_t) ** 2),
        "h_t": h_t,
        "h_r": h_r,
        "grazing_rad": psi,
        "el_tx_dir_rad": elevation(h_r - h_t, d_2d),
        "el_tx_ref_rad": -psi,
        "az_tx_rad": bearing(-u[..., 0], -u[..., 1]),
        "az_b_rad": az_b,
        "dep_b_rad": dep_b,
        "az_b_ref_rad": az_b2,
        "dep_b_ref_rad": dep_b2,
    }
