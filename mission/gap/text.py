"""The diagnosis as text that reads at 80 columns: a plain-language summary, one line per ladder
rung, short tables; the full tables (every candidate on every rung, every flagged bin, every flight)
go to ``details.txt`` in the report folder and to ``gap.json``.

Why: at 80 columns the wide rich tables of earlier rounds wrapped into unreadable cells.  Every
table here has columns whose widths add up to less than 80 (``WIDTH``), labels are short
(``labels.short_labels``), and what a reader needs first is a sentence, not a table.
"""

from __future__ import annotations

import textwrap
from typing import Any

import numpy as np
from rich.console import Console

from mission.gap.align import SEGMENTS
from mission.gap.diagnose import Diagnosis, rung_table
from mission.gap.fit import RANKING_RULE
from mission.gap.structure import WITHIN_FLIGHT
from mission.gap.temporal import NAME

WIDTH = 80
PLAIN: dict[str, str] = {
    "rx_pattern": "the UAV antenna's pattern",
    "rx_mounting": "the UAV antenna's heading on the airframe",
    "tx_pattern": "the rover antenna's pattern",
    "tx_mounting": "the rover antenna's heading",
    "tx_tilt": "a tilted rover antenna",
    "ground_reflection": "the ground-reflected ray",
    "attitude": "the UAV's roll, pitch and yaw",
    "yaw_attitude": "the UAV's heading (yaw)",
    "leg_shadowing": "shadowing by the UAV's legs",
    "path_gain_slope": "a steeper path loss",
    "time_offset": "a lag between RSS and telemetry",
    "receiver": "the receiver's floor or saturation",
    "rx_gain_map": "the UAV antenna's gain over body angles",
    "tx_gain_map": "the rover antenna's gain by direction",
    "excess_loss": "an extra loss growing with distance",
    "near_nadir": "a loss in a band of angles below the UAV",
    "spatial_shadowing": "shadowing correlated over the ground",
    "site_map": "shadowing shared by flights at the same rover position",
}


def _added(label: str) -> str:
    return label.split(" + ")[-1]


def summary_paragraph(d: Diagnosis) -> str:
    """One paragraph: what the model misses, worth how many dB, and what is left (size, correlation
    range)."""
    rows = rung_table(d)
    p90 = [r["pooled"]["p90_abs_db"] for r in rows]
    parts = []
    for i, (r, prev) in enumerate(zip(rows[1:], p90, strict=False)):
        what = PLAIN.get(r["added"], r["added"])
        x = next((q for q in d.rungs[i].ranking if q.name == r["added"]), None)
        like = x.fold_params[0].get("resembles") if x is not None and x.fold_params else None
        like = f" (like {like})" if like else ""
        parts.append(f"{what}{like}, worth {prev - r['pooled']['p90_abs_db']:.1f} dB")
    base = f"Held-out p90 |error| of {d.base_label}: {p90[0]:.1f} dB. "
    if parts:
        s = (
            base
            + "The model misses "
            + "; ".join(parts)
            + f" (p90 {p90[0]:.1f} -> {p90[-1]:.1f} dB). "
        )
    else:
        s = base + "No candidate effect closes a significant part of the gap. "
    # a decided test changes what is added: say so (all of them in details.txt)
    for fr in d.frames.values():
        if fr["winner"] is not None:
            s += " " + fr["text"]
    s += _time_sentence(d)
    st = d.structure.get("final", {})
    if st:
        s += " " + verdict_sentence(
            st, _speed(d), "After it, what is left" if parts else "What is left"
        )
    nn = d.near_nadir
    if nn and not nn.get("found"):
        s += " " + nn["statement"]
    return " ".join(s.split())


def verdict_sentence(st: dict[str, Any], speed: float, lead: str = "What is left") -> str:
    """The one verdict on a rung's residual (``structure.structure_verdict``) in words a reader can
    act on; the summary and the structure lines both use it, so they cannot disagree."""
    te, sp, al = st.get("test", {}), st.get("spatial", {}), st.get("along_path", {})
    std, v = st.get("residual_std_db", float("nan")), st.get("verdict")
    ratio = (
        f"near/all-pair semivariance {te.get('ratio', float('nan')):.2f}, upper bound "
        f"{te.get('ratio_ci', [float('nan')] * 2)[1]:.2f}"
    )
    if v == "correlated shadowing":
        return (
            f"{lead} ({std:.1f} dB) is shadowing fixed to the ground: near samples over the "
            "same ground are "
            f"alike ({ratio} < 0.8), {te.get('correlated_std_db', float('nan')):.1f} dB of it "
            "correlated over "
            f"about {sp.get('corr_len', float('nan')):.0f} m, that no model here predicts on "
            "unflown ground, "
            f"plus {sp.get('nugget_db', float('nan')):.1f} dB of white noise."
        )
    if v == WITHIN_FLIGHT:
        return (
            f"{lead} ({std:.1f} dB) is correlated along each flight ({al['sigma_db']:.1f} dB "
            "over about "
            f"{al['corr_len']:.0f} s, {al['corr_len'] * speed:.0f} m at {speed:.1f} m/s; white "
            "noise "
            f"{al['nugget_db']:.1f} dB) but is not shown to repeat over the same ground "
            f"({ratio}, not below "
            "0.8): it follows the flight rather than the ground (its own path's shadowing seen "
            "once, a gain "
            "changing over the flight, or a per-flight state such as the rover's heading or "
            "transmit power). "
            "A ground map will not predict it on new flights; per-flight terms (time_drift, "
            "chunks held out) "
            "or the same ground flown twice in a flight can tell which."
        )
    return f"{lead} looks like white noise of {std:.1f} dB ({ratio})."


def _time_sentence(d: Diagnosis) -> str:
    """Whether an effect is better explained along time than by geometry, or what time could
    show."""
    first = d.rungs[0].ranking
    t = next((r for r in first if r.name == NAME), None)
    geo = next((r for r in first if r.name != NAME and r.significant), None)
    if t is not None and t.significant and (geo is None or first.index(t) < first.index(geo)):
        other = (
            f" against {geo.rel_reduction:.0%} for the best geometric candidate ({geo.name})"
            if geo
            else ""
        )
        return (
            " The first effect is better explained along the flight's time than by geometry: "
            "a gain drifting "
            f"or stepping over each flight reduces the held-out loss {t.rel_reduction:.0%}{other}."
        )
    if any(r.added == NAME for r in d.rungs):
        return ""
    tp = d.time_power
    return (" " + tp["statement"]) if tp.get("statement") else ""


def _speed(d: Diagnosis) -> float:
    """Median ground speed of the flights (m/s), to turn a correlation time into a distance."""
    v = [
        np.hypot(*np.diff(f.enu_m[:, :2], axis=0).T) / np.maximum(np.diff(f.t_s), 1e-6)
        for f in d.flights
        if f.t_s is not None and len(f) > 2
    ]
    return float(np.median(np.concatenate(v))) if v else float("nan")


def wrap(text: str, width: int = WIDTH) -> str:
    return "\n".join(textwrap.wrap(text, width))


def _table(title: str, cols: list[tuple[str, int, str]], rows: list[list[str]]) -> str:
    """A plain text table; ``cols``: (header, width, '<' or '>'); cells longer than their width are
    cut."""

    def line(cells: list[str]) -> str:
        out = []
        for (_, w, al), c in zip(cols, cells, strict=True):
            c = c if len(c) <= w else c[: w - 1] + "~"
            out.append(f"{c:{al}{w}}")
        return " ".join(out).rstrip()

    head = line([h for h, _, _ in cols])
    return "\n".join([title, head, "-" * min(WIDTH, len(head)), *[line(r) for r in rows]])


def ladder_text(d: Diagnosis) -> str:
    """One line per rung: what was added, held-out median/p90/rms, p90 gained, size where it acts,
    loc. error."""
    loc = {row["rung"]: row for row in d.localization}
    rows, prev = [], None
    for row in rung_table(d):
        s = row["pooled"]
        fp = d.footprints.get(row["rung"]) or {}
        le = loc.get(row["rung"], {}).get("mean_error_m")
        gain = "" if prev is None else f"{prev - s['p90_abs_db']:+.1f}"
        rows.append(
            [
                ("+ " if row["added"] else "") + (row["added"] or d.base_label),
                f"{s['median_abs_db']:.1f}",
                f"{s['p90_abs_db']:.1f}",
                f"{s['rms_db']:.1f}",
                gain,
                f"{fp['size_db']:.1f}" if fp else "",
                "" if le is None else f"{le:.0f}",
            ]
        )
        prev = s["p90_abs_db"]
    cols = [
        ("rung", 24, "<"),
        ("med dB", 7, ">"),
        ("p90 dB", 7, ">"),
        ("rms dB", 7, ">"),
        ("p90 gain", 8, ">"),
        ("size dB", 7, ">"),
        ("loc m", 6, ">"),
    ]
    return _table(
        f"The ladder (held-out, {d.config['split']} split; size: where it acts)", cols, rows
    )


def ranking_text(d: Diagnosis, k: int = 0, top: int | None = 6) -> str:
    """Candidates tried on rung ``k``: p90 after, relative loss reduction, its lower bound,
    significant."""
    r = d.rungs[k]
    rows = [
        [
            x.name,
            x.tier,
            f"{x.p90_after:.1f}",
            f"{x.rel_reduction:+.1%}",
            f"{x.ci_lo:+.2f}",
            "yes" if x.significant else "no",
        ]
        for x in r.ranking[:top]
    ]
    cols = [
        ("candidate", 18, "<"),
        ("tier", 9, "<"),
        ("p90 after", 9, ">"),
        ("loss red.", 9, ">"),
        ("lower bd", 8, ">"),
        ("signif.", 7, ">"),
    ]
    more = "" if top is None or len(r.ranking) <= top else f" (top {top} of {len(r.ranking)})"
    return _table(f"Candidates on '{_added(r.label)}'{more}", cols, rows)


def flights_text(d: Diagnosis) -> str:
    """Per flight: samples and held-out p90 on the first and last rung."""
    first, last = d.rungs[0], d.rungs[-1]
    rows = []
    for k, f in enumerate(d.flights):
        a, b = (np.abs(x[k][np.isfinite(x[k])]) for x in (first.residuals, last.residuals))
        rows.append(
            [
                f.name,
                str(len(f)),
                f"{np.quantile(a, 0.9):.1f}" if a.size else "",
                f"{np.quantile(b, 0.9):.1f}" if b.size else "",
            ]
        )
    cols = [("flight", 18, "<"), ("n", 6, ">"), ("p90 base", 9, ">"), ("p90 final", 9, ">")]
    return _table("Flights (held-out p90 |error| dB)", cols, rows)


def structure_text(d: Diagnosis) -> str:
    out = []
    for k, st in d.structure.items():
        if "spatial" not in st:
            continue
        sp, te, al = st["spatial"], st.get("test", {}), st.get("along_path", {})
        out.append(
            wrap(
                f"What is left ({k} rung): {st['verdict']}; near/all-pair semivariance "
                f"{te.get('ratio', float('nan')):.2f}, correlated std "
                f"{te.get('correlated_std_db', 0):.1f} "
                f"dB; over space sigma {sp['sigma_db']:.1f} dB, L {sp['corr_len']:.0f} m "
                f"[{sp['corr_len_ci'][0]:.0f}, {sp['corr_len_ci'][1]:.0f}], nugget "
                f"{sp['nugget_db']:.1f} dB; "
                f"along the path sigma {al.get('sigma_db', float('nan')):.1f} dB over "
                f"{al.get('corr_len', float('nan')):.0f} s, correlated fraction "
                f"{al.get('correlated_fraction', float('nan')):.2f}."
            )
        )
    return "\n".join(out)


def report_text(d: Diagnosis) -> str:
    """The terminal report (every line at most ``WIDTH`` characters)."""
    parts = [
        wrap(summary_paragraph(d)),
        ladder_text(d),
        ranking_text(d, 0),
        flights_text(d),
        structure_text(d),
        "Details: every candidate on every rung and the flagged bins in details.txt and gap.json "
        "(--report DIR, --json).",
    ]
    return "\n\n".join(wrap(p) if "\n" not in p else p for p in parts if p)


def details_text(d: Diagnosis) -> str:
    """Everything else, still at 80 columns: the reference models per flight, the flagged bins,
    every ranking."""
    parts = [report_text(d)]
    rows = [
        [
            g.name,
            fn,
            str(s["n"]),
            f"{s['median_abs_db']:.1f}",
            f"{s['p90_abs_db']:.1f}",
            f"{s['rms_db']:.1f}",
        ]
        for g in d.gaps
        for fn, s in [*g.per_flight.items(), ("pooled", g.pooled)]
    ]
    parts.append(
        _table(
            "Reference models, in sample (offset fitted per flight)",
            [
                ("model", 16, "<"),
                ("flight", 18, "<"),
                ("n", 6, ">"),
                ("med dB", 7, ">"),
                ("p90 dB", 7, ">"),
                ("rms dB", 7, ">"),
            ],
            rows,
        )
    )
    rows = []
    for b in d.breakdown:
        for i in np.nonzero(b.flagged)[0]:
            lab = (
                SEGMENTS[int(b.centers[i])]
                if b.variable == "segment"
                else f"{b.edges[i]:g}-{b.edges[i + 1]:g}"
            )
            rows.append(
                [
                    b.variable,
                    lab,
                    str(int(b.count[i])),
                    f"{b.mean[i]:+.1f}",
                    f"[{b.lo[i]:+.1f}, {b.hi[i]:+.1f}]",
                ]
            )
    parts.append(
        _table(
            f"Where {d.base_label} departs (bins whose 95 % CI excludes 0)",
            [
                ("variable", 18, "<"),
                ("bin", 10, "<"),
                ("n", 6, ">"),
                ("mean dB", 8, ">"),
                ("95 % CI dB", 16, ">"),
            ],
            rows,
        )
    )
    for k, r in enumerate(d.rungs):
        if r.ranking:
            parts.append(ranking_text(d, k, top=None))
        if r.frame is not None:
            parts.append(
                wrap(
                    f"On '{_added(r.label)}': "
                    + r.frame["text"]
                    + " Rule: "
                    + r.frame["rule"]
                    + "."
                )
            )

    parts.append(wrap("Ranking rule: " + RANKING_RULE))
    return "\n\n".join(parts) + "\n"


def print_report(d: Diagnosis, console: Any = None) -> None:
    """Print ``report_text`` (plain text: no markup, so what is printed is what the test
    measures)."""
    c = console or Console()
    c.print(report_text(d), markup=False, highlight=False, soft_wrap=True)
