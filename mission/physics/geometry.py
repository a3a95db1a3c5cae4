"""Frames and line-of-sight angles (SPEC section 1), shared by physics, simulation and the gap tool.

Local frame ENU (x east, y north, z up). Attitude = roll, pitch, yaw of body FRD w.r.t. NED
(MAVLink): ``R_nb = Rz(yaw) Ry(pitch) Rx(roll)`` maps body vectors to NED. A vector ``u`` (NED) seen
from the body is ``u_b = R_nb^T u``; ``az_b = atan2(u_b.y, u_b.x)`` in [0, 2 pi) (0 = nose, positive
to the right) and ``dep_b = asin(u_b.z / |u|)`` (positive below the body plane). The paper's ``R =
R_r R_p R_y`` applied to a pointing vector (eqs. 3-6) is the same idea; the project uses this
physically consistent transform.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

TWO_PI = 2.0 * np.pi


def enu_to_ned(v_enu: ArrayLike) -> NDArray[np.float64]:
    """(e, n, u) -> (n, e, d) on the last axis."""
    v = np.asarray(v_enu, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def as_attitude(attitude_rad: ArrayLike | None, n: int) -> NDArray[np.float64]:
    """Attitude as an (n, 3) array of roll, pitch, yaw (rad); None means level, nose north."""
    if attitude_rad is None:
        return np.zeros((n, 3))
    att = np.asarray(attitude_rad, dtype=float)
    if att.ndim == 1 and att.shape == (3,):
        att = np.broadcast_to(att, (n, 3))
    if att.shape != (n, 3):
        raise ValueError(
            f"attitude must have shape ({n}, 3) (roll, pitch, yaw rad), got {att.shape}"
        )
    return att


def rotation_nb(attitude_rad: ArrayLike) -> NDArray[np.float64]:
    """R_nb = Rz(yaw) Ry(pitch) Rx(roll), shape (..., 3, 3): body FRD -> NED."""
    att = np.asarray(attitude_rad, dtype=float)
    cr, sr = np.cos(att[..., 0]), np.sin(att[..., 0])
    cp, sp = np.cos(att[..., 1]), np.sin(att[..., 1])
    cy, sy = np.cos(att[..., 2]), np.sin(att[..., 2])
    R = np.empty(att.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def body_from_enu_matrix(attitude_rad: ArrayLike) -> NDArray[np.float64]:
    """C with ``u_b = C @ u_enu`` (= R_nb^T P, P the ENU->NED permutation), shape (..., 3, 3).

    Depends only on the sample, so it is computed once per sample and reused for every transmitter.
    """
    Rt = np.swapaxes(rotation_nb(attitude_rad), -1, -2)
    return np.stack([Rt[..., :, 1], Rt[..., :, 0], -Rt[..., :, 2]], axis=-1)


def body_from_enu_planes(attitude_rad: ArrayLike, dtype: DTypeLike = np.float64) -> NDArray:
    """``body_from_enu_matrix`` laid out as (3, 3, N), each C[i, j] contiguous over the samples.

    The fast propagation path reads the nine entries as whole arrays; writing them straight into
    this layout avoids the strided (N, 3, 3) matrix and its transposed copy (the per-sample cost of
    one flight).
    """
    att = np.asarray(attitude_rad, dtype=float)
    cr, sr = np.cos(att[:, 0]), np.sin(att[:, 0])
    cp, sp = np.cos(att[:, 1]), np.sin(att[:, 1])
    cy, sy = np.cos(att[:, 2]), np.sin(att[:, 2])
    C = np.empty((3, 3, att.shape[0]), dtype=dtype)
    # C[i, 0] = R[1, i] (east), C[i, 1] = R[0, i] (north), C[i, 2] = -R[2, i] (up), R = R_nb
    C[0, 0] = sy * cp
    C[0, 1] = cy * cp
    C[0, 2] = sp
    C[1, 0] = sy * sp * sr + cy * cr
    C[1, 1] = cy * sp * sr - sy * cr
    C[1, 2] = -cp * sr
    C[2, 0] = sy * sp * cr - cy * sr
    C[2, 1] = cy * sp * cr + sy * sr
    C[2, 2] = -cp * cr
    return C


def body_vectors(u_ned: ArrayLike, attitude_rad: ArrayLike | None) -> NDArray[np.float64]:
    """u_b = R_nb^T u for u (..., 3) NED and attitude broadcastable to (..., 3)."""
    u = np.asarray(u_ned, dtype=float)
    if attitude_rad is None:
        return u
    R = rotation_nb(attitude_rad)
    return np.einsum("...ki,...k->...i", R, u)


def body_azimuth(ub_x: ArrayLike, ub_y: ArrayLike, signed: bool = False) -> NDArray:
    """az_b = atan2(u_b.y, u_b.x) in [0, 2 pi): 0 = nose, positive to the right; keeps a float32
    input float32.

    ``signed``: atan2's own range (-pi, pi], for periodic uses (a Fourier basis) where the wrap
    would only round.
    """
    az = np.arctan2(ub_y, ub_x)
    return az if signed else np.mod(az, TWO_PI)


def sin_depression(ub_z: ArrayLike, r: ArrayLike) -> NDArray:
    """sin dep_b = u_b.z / |u|, clipped to [-1, 1]; ``r`` = |u| > 0 (the free-form maps'
    variable)."""
    return np.clip(np.asarray(ub_z) / r, -1.0, 1.0)


def depression(ub_z: ArrayLike, r: ArrayLike) -> NDArray:
    """dep_b = asin(u_b.z / |u|) (rad, positive below the body plane); ``r`` = |u| > 0; dtype
    kept."""
    return np.arcsin(sin_depression(ub_z, r))


def body_angles(
    u_ned: ArrayLike, attitude_rad: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Body azimuth az_b in [0, 2 pi) and depression dep_b (rad) of the NED vector(s) u (UAV ->
    target).

    ``attitude_rad`` (..., 3) roll, pitch, yaw broadcasts against u's leading shape; None = level,
    yaw 0.
    """
    ub = body_vectors(u_ned, attitude_rad)
    r = np.linalg.norm(ub, axis=-1)
    az_b = body_azimuth(ub[..., 0], ub[..., 1])
    dep_b = depression(ub[..., 2], np.where(r > 0, r, 1.0))
    return az_b, dep_b


def bearing(dx_east: ArrayLike, dy_north: ArrayLike, signed: bool = False) -> NDArray:
    """Compass bearing (clockwise from north) of a horizontal ENU vector, in [0, 2 pi); float32
    stays float32.

    The UAV seen from the transmitter is ``bearing(-dx, -dy)`` of the link delta.  ``signed``: (-pi,
    pi] as in ``body_azimuth``.
    """
    az = np.arctan2(dx_east, dy_north)
    return az if signed else np.mod(az, TWO_PI)


# -- the link UAV -> transmitter from its ENU components (dtype-preserving: the fast paths run in
# float32)
def link_delta(
    tx_enu: ArrayLike, rx_enu: ArrayLike, dtype: DTypeLike | None = None
) -> tuple[NDArray, NDArray, NDArray]:
    """(dx, dy, dz) = p_tx - p_uav (ENU) on the last axis, broadcast; differenced in the inputs'
    precision, then cast to ``dtype`` (None: kept), so float32 work on large coordinates keeps the
    difference's precision."""
    tx, rx = np.asarray(tx_enu), np.asarray(rx_enu)
    out = tuple(tx[..., i] - rx[..., i] for i in range(3))
    return out if dtype is None else tuple(np.asarray(v).astype(dtype) for v in out)


def horizontal_distance(dx: ArrayLike, dy: ArrayLike) -> NDArray:
    """d_2D = sqrt(dx^2 + dy^2), the ground distance UAV -> transmitter."""
    return np.hypot(dx, dy)


def slant_distance(dx: ArrayLike, dy: ArrayLike, dz: ArrayLike) -> NDArray:
    """d_los = |p_tx - p_uav|, the 3D (line-of-sight) distance."""
    dx, dy, dz = np.asarray(dx), np.asarray(dy), np.asarray(dz)
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def elevation(dz: ArrayLike, d_2d: ArrayLike) -> NDArray:
    """Up-positive elevation atan2(dz, d_2D) of the far end of a link seen from the level frame
    (rad)."""
    return np.arctan2(dz, d_2d)


def sin_elevation(dz: ArrayLike, d_los: ArrayLike) -> NDArray:
    """sin el = dz / d_los clipped to [-1, 1]: the up-positive elevation's sine of the far end of a
    link."""
    return np.clip(np.asarray(dz) / d_los, -1.0, 1.0)


def heading_frame_angles(
    dx: NDArray, dy: NDArray, dz: NDArray, yaw_rad: ArrayLike, d_2d: NDArray | None = None
) -> tuple[NDArray, NDArray]:
    """Elevation (up-positive, = -dep_b) and body azimuth az_b of the link (dx, dy, dz) = p_tx -
    p_uav (ENU) seen from a body frame turned to heading ``yaw_rad`` but level (roll = pitch = 0),
    in the inputs' dtype.

    This is ``body_angles`` at attitude (0, 0, yaw) without the rotation matrix: az_b = bearing -
    yaw; it is the frame of a receiver antenna hanging below the body whose tilt is not modelled
    (the self-calibrating grid).
    """
    el = elevation(dz, np.sqrt(dx * dx + dy * dy) if d_2d is None else d_2d)
    return el, np.mod(np.arctan2(dx, dy) - yaw_rad, TWO_PI)
