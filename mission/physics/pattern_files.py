"""Antenna pattern files: the tabulated CSV format (read and write) and measured AERPAW chamber
files.

Tabulated CSV format (:func:`load_pattern_csv`, :func:`save_pattern_csv`)
------------------------------------------------------------------------ UTF-8 text. Lines starting
with ``#`` are comments (source, licence, normalisation). The first other line is the header: a
label cell (e.g. ``el\\az``) then the azimuths in degrees, strictly ascending, distinct modulo 360
(the grid is periodic in azimuth; e.g. 0, 3, ..., 357). Each further line is an elevation in degrees
(strictly ascending over the rows, within [-90, 90]) then the gains in dBi, one per azimuth. Gains
are interpolated bilinearly in dB (periodic in azimuth); elevations outside the table's range are
clamped to its first/last row. Example::

    # my antenna, 3.3 GHz, gain dBi
    el\\az,0,90,180,270
    -90,-10,-10,-10,-10
    0,2,2,1.5,2
    90,-10,-10,-10,-10

Measured AERPAW files (:func:`load_aerpaw_pattern`)
--------------------------------------------------- AERPAW "3D antenna radiation pattern
measurement" (anechoic chamber, 3300 MHz): rows ``Phi(rad) Theta(rad) ETotal_dB EPhi_dB ETheta_dB
EPhi_phase ETheta_phase`` with Phi 0..177 deg and Theta -180..180 deg in 3 deg steps. Theta is the
polar angle from the antenna axis in the cut plane at azimuth Phi; negative Theta is the opposite
half of that cut (azimuth Phi + 180). Direction ``(sin T cos P, sin T sin P, cos T)``, so ``el = 90
- |Theta|`` and ``az = Phi`` (Theta >= 0) or ``Phi + 180`` (Theta < 0). Evidence: all Phi give the
same value at Theta = 0 and at Theta = +-180 (the poles of the cut system); the upside-down
RM-WB1-DN file matches the right-side-up one turned 180 degrees about the chamber x axis (2.3 dB
rms, against 5-6 dB for any turn about z), so the antenna's axis is the chamber z axis; and the
dipole-like SA-1400-5900 has its deep null within about 20 degrees of Theta = 0. The right-side-up
RM-WB1-DN at 3.3 GHz is NOT a donut: its maximum (~+6 dBi) is within about 15 degrees of its axis
(z_a up, away from the base) and it is weakest below (Theta near +-180). ETotal_dB is relative; it
is normalised to directivity (dBi) by integrating the radiated power over the sphere: ``G = E + 10
log10(4 pi / sum 10^(E/10) cos(el) d_el d_az)`` (trapezoid in elevation, rectangle in the periodic
azimuth), i.e. a lossless antenna (efficiency 1).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.physics.patterns import TabulatedPattern, sphere_integral

AERPAW_CREDIT = (
    'AERPAW "3D antenna radiation pattern measurement" data set (anechoic chamber), as carried '
    "in anilgurses/CHEM data/antenna (commit 6b9e58f8)"
)


def load_pattern_csv(path: str | Path, name: str | None = None) -> TabulatedPattern:
    """Read a tabulated pattern in the module's CSV format; bad input raises InputError (file,
    row)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise InputError(
            f"cannot read antenna pattern: {e.strerror or e}", source=str(path)
        ) from None
    header: list[float] | None = None
    els: list[float] = []
    rows: list[list[float]] = []
    notes: list[str] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            notes.append(s.lstrip("# "))
            continue
        cells = [c.strip() for c in s.split(",")]
        if header is None:
            try:
                header = [float(c) for c in cells[1:]]
            except ValueError:
                raise InputError(
                    "header must be a label then azimuths in degrees", source=str(path), row=lineno
                ) from None
            if len(header) < 2:
                raise InputError("need at least 2 azimuth columns", source=str(path), row=lineno)
            continue
        if len(cells) != len(header) + 1:
            raise InputError(
                f"expected {len(header) + 1} cells (elevation + {len(header)} gains), "
                f"got {len(cells)}",
                source=str(path),
                row=lineno,
            )
        try:
            vals = [float(c) for c in cells]
        except ValueError:
            raise InputError("non-numeric value", source=str(path), row=lineno) from None
        if not all(math.isfinite(v) for v in vals):
            raise InputError("non-finite value", source=str(path), row=lineno)
        if els and vals[0] <= els[-1]:
            raise InputError(
                "elevations must be strictly ascending",
                source=str(path),
                row=lineno,
                field="elevation",
            )
        if not -90.0 <= vals[0] <= 90.0:
            raise InputError(
                "elevation must be within [-90, 90] deg",
                source=str(path),
                row=lineno,
                field="elevation",
            )
        els.append(vals[0])
        rows.append(vals[1:])
    if header is None or len(els) < 2:
        raise InputError("need a header row and at least 2 elevation rows", source=str(path))
    az = np.asarray(header)
    if np.any(np.diff(az) <= 0) or az[-1] - az[0] >= 360.0:
        raise InputError(
            "azimuths must be strictly ascending and distinct modulo 360",
            source=str(path),
            row=None,
            field="azimuth",
        )
    return TabulatedPattern(
        np.asarray(els), az, np.asarray(rows), name=name or path.stem, note="; ".join(notes)
    )


def save_pattern_csv(
    pattern: TabulatedPattern, path: str | Path, comments: tuple[str, ...] = ()
) -> None:
    """Write a tabulated pattern in the module's CSV format (gains to 0.01 dB)."""
    lines = [f"# {c}" for c in comments]
    lines.append("el\\az," + ",".join(f"{a:g}" for a in pattern.az_deg))
    for e, row in zip(pattern.el_deg, pattern.gain, strict=True):
        lines.append(f"{e:g}," + ",".join(f"{v:.2f}" for v in row))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def load_aerpaw_pattern(path: str | Path, name: str | None = None) -> TabulatedPattern:
    """Read a measured AERPAW pattern file (see module docstring), normalised to directivity
    (dBi)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as e:
        raise InputError(
            f"cannot read antenna pattern: {e.strerror or e}", source=str(path)
        ) from None
    start = next((k for k, s in enumerate(lines) if s.strip().lower().startswith("phi")), None)
    if start is None:
        raise InputError(
            "no 'Phi Theta ...' header line: not an AERPAW pattern file", source=str(path)
        )
    data = []
    for lineno, s in enumerate(lines[start + 1 :], start=start + 2):
        if not s.strip():
            continue
        try:
            vals = [float(c) for c in s.split()[:3]]
        except ValueError:
            raise InputError("non-numeric value", source=str(path), row=lineno) from None
        if len(vals) < 3:
            raise InputError("expected Phi, Theta, ETotal_dB", source=str(path), row=lineno)
        data.append(vals)
    a = np.asarray(data)
    phi = np.round(np.degrees(a[:, 0]), 6)
    theta = np.round(np.degrees(a[:, 1]), 6)
    P, T = np.unique(phi), np.unique(theta)
    if a.shape[0] != P.size * T.size or not np.allclose(T, -T[::-1]) or T.min() > -179.999:
        raise InputError(
            "expected a full Phi x Theta grid with Theta symmetric over [-180, 180]",
            source=str(path),
        )
    dphi = np.diff(P)
    if not np.allclose(dphi, dphi[0]) or not np.isclose(P[-1] + dphi[0], 180.0):
        raise InputError("expected Phi uniform over [0, 180)", source=str(path))
    E = np.full((P.size, T.size), np.nan)
    E[np.searchsorted(P, phi), np.searchsorted(T, theta)] = a[:, 2]
    Tpos = T[T >= 0]  # 0 .. 180
    el = 90.0 - Tpos[::-1]  # -90 .. 90 ascending
    it_pos = np.searchsorted(T, Tpos[::-1])  # Theta = 90 - el
    it_neg = np.searchsorted(T, -Tpos[::-1])  # Theta = -(90 - el): the half-plane Phi + 180
    az = np.concatenate([P, P + 180.0])
    g = np.concatenate([E[:, it_pos].T, E[:, it_neg].T], axis=1)  # (el, az)
    # directivity normalisation: (1 / 4 pi) * integral of 10^(g/10) dOmega = 1
    offset = 10.0 * np.log10(4.0 * np.pi / sphere_integral(el, az, 10.0 ** (g / 10.0)))
    return TabulatedPattern(
        el,
        az,
        g + offset,
        name=name or path.stem,
        note=f"{path.name}: ETotal_dB + {offset:.3f} dB (directivity by integration)",
    )
