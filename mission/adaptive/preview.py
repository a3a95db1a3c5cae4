"""``rfsl preview --adaptive``: the adaptive finish's expected error against the fixed trajectory's.

Why simulated flights and not the preview's error map: the adaptive path depends on what the flight
measured, so it has no single geometry to map; a few paired flights (``compare.pair``) under the
physics family give the expected errors of both with their intervals, the adaptive rounds flown and
the time used.
"""

from __future__ import annotations

from mission.adaptive.compare import pair, summarize_pairs
from mission.adaptive.config import AdaptiveSpec
from mission.adaptive.feasibility import assert_adaptive
from mission.console import progress_bar
from mission.errors import InputError


def adaptive_rows(spec, flights: int, seed: int, family: str, console) -> list[tuple[str, str]]:
    """(label, value) rows for the preview table (a progress bar while the flights are
    simulated)."""
    if not 1 <= flights <= 1000:
        raise InputError(f"must be 1..1000, got {flights}", field="--flights")
    a = spec.adaptive or AdaptiveSpec()
    assert_adaptive(spec, a)
    rows = []
    with progress_bar("adaptive vs fixed", console) as prog:
        task = prog.add_task("flights", total=flights)
        for i in range(flights):
            rows.append(pair(spec, a, family, seed, i))
            prog.update(task, completed=i + 1)
    s = summarize_pairs(rows)
    if not s["n"]:
        return [("adaptive vs fixed", "no flight could be localized")]
    f, ad = s["fixed"], s["adaptive"]
    where = f"{s['n']} simulated flights, {family} family, as localize answers"
    out = [
        (f"expected error, fixed ({where})", f"{f['mean'].fmt()} m, p90 {f['p90_m']:.0f} m"),
        (
            f"expected error, adaptive after {a.survey_s:g} s",
            f"{ad['mean'].fmt()} m, p90 {ad['p90_m']:.0f} m",
        ),
        ("adaptive - fixed (paired)", f"{ad['diff'].fmt()} m"),
        (
            "adaptive rounds / flight time",
            f"{ad['rounds']:.1f} / {ad['duration_s']:.0f} s (fixed {f['duration_s']:.0f} s)",
        ),
        (
            "90 % region covers truth (fixed / adaptive)",
            f"{100 * f['coverage']:.0f} / {100 * ad['coverage']:.0f} %",
        ),
    ]
    if s["fast"]:
        out.append(("fast estimate (3 min)", f"{s['fast'][0].fmt()} m"))
    return out
