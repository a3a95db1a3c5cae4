"""Legs planned from the live posterior: the survey cut, the square around the estimate,
fence/altitude/budget.

One round = a square of half side ``radius_m`` centred on the live estimate, flown corner to corner
and closed, then through its centre (RSS gradients are steepest near the transmitter, so four sides
and a pass over the estimate constrain it from every side).  Every round is checked before it is
sent: the fence and altitude limits with ``trajectory.checks.check_mission`` (the same rule as the
mission's own waypoints), the time with ``plan_profile`` from where the current leg ends through the
round, then the autopilot's own return and landing from the round's end
(``trajectory.autopilot.ReturnModel``: its climb to its return altitude, its landing speeds, its
disarm), plus a reserve, against what is left of the budget.  A round that
does not fit is moved inside the fence (its centre towards the flight area's interior) or shrunk
(down to ``min_radius_m``) and says so; otherwise it is refused.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mission.geo import square_grid
from mission.localize.methods import JUDGED_PICK
from mission.spec import TrajectorySpec
from mission.trajectory.autopilot import ReturnModel
from mission.trajectory.checks import check_mission
from mission.trajectory.kinematics import FlightProfile, plan_profile

# A hypothesis whose neighbourhood keeps less than this share of the posterior mass it held when
# the round was planned is ruled out by the round (``verdict``)
RULED_OUT_DROP = 0.25


def survey_profile(spec, survey_s: float) -> FlightProfile:
    """The trajectory's waypoints flown from the first one for ``survey_s`` seconds (cut inside a
    leg)."""
    wps = spec.waypoints_enu()
    kin = spec.kinematics()
    prof = plan_profile(wps, kin)
    if survey_s >= prof.duration_s or len(wps) < 2:
        return prof
    k = int(np.searchsorted(prof.t_vertex, survey_s, side="right"))
    cut = prof.position(np.array([survey_s]))[0]
    return plan_profile(np.vstack([wps[:k], cut]), kin)


def survey_spec(spec, survey_s: float):
    """``spec`` whose trajectory is the survey part only (explicit waypoints): what is uploaded
    first."""
    wps = survey_profile(spec, survey_s).vertices
    return dataclasses.replace(spec, trajectory=TrajectorySpec("waypoints", {}, wps))


def flown_ahead(spec):
    """The part of ``spec`` known before take-off: an adaptive mission's survey (its rounds are
    planned in flight around the live estimate and cannot be drawn ahead), else the whole mission.
    Why: a network that answers an adaptive flight's survey is trained on surveys."""
    a = spec.adaptive
    return survey_spec(spec, a.survey_s) if a is not None and a.enabled else spec


def box_pattern(centre, r: float, alt: float, start=None) -> np.ndarray:
    """(6, 3) waypoints: the four corners of a square of half side ``r`` about ``centre``, closed,
    then the centre; starting at the corner nearest ``start`` (saves a crossing)."""
    c = np.asarray(centre, dtype=float)[:2]
    corners = c + r * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    if start is not None:
        k = int(np.argmin(np.hypot(*(corners - np.asarray(start, dtype=float)[:2]).T)))
        corners = np.roll(corners, -k, axis=0)
    xy = np.vstack([corners, corners[:1], c[None, :]])
    return np.column_stack([xy, np.full(len(xy), float(alt))])


def fit_centre(spec, want_xy, r: float, step_m: float = 2.0) -> np.ndarray | None:
    """The centre nearest ``want_xy`` whose square (half side ``r``) keeps the fence margin (None:
    nowhere).

    The flight area is convex (``geo.Area``), so corners inside with the margin keep every leg
    inside too."""
    area, margin = spec.field.flight_area, spec.fence_margin_m
    want = np.asarray(want_xy, dtype=float)[:2]
    offs = r * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    if min(area.signed_distance(want + offs)) >= margin:
        return want
    g = square_grid(area.bounds, step_m).reshape(-1, 2)
    g = g[area.signed_distance(g) >= margin + r]  # a necessary condition first (cheap)
    if not len(g):
        return None
    ok = np.min([area.signed_distance(g + o) for o in offs], axis=0) >= margin
    if not ok.any():
        return None
    g = g[ok]
    return g[int(np.argmin(np.hypot(*(g - want).T)))]


def posterior_candidates(post, k: int = 4, sep_m: float = 40.0) -> list[list[float]]:
    """Up to ``k`` distinct hypotheses [x, y, mass] of a grid posterior, most probable first: greedy
    peaks at least ``sep_m`` apart, each with the mass within ``sep_m / 2`` of it."""
    pts = post.grid.reshape(-1, 2)
    p = post.prob.ravel()
    order = np.argsort(p)[::-1]
    out: list[list[float]] = []
    taken = np.zeros(len(p), dtype=bool)
    for j in order[: max(1, int(0.2 * len(p)))]:
        if taken[j]:
            continue
        d = np.hypot(*(pts - pts[j]).T)
        out.append([float(pts[j, 0]), float(pts[j, 1]), float(p[d <= sep_m / 2].sum())])
        taken |= d < sep_m
        if len(out) == k:
            break
    return out


def choose_target(est_xy, candidates, visited, visit_m: float) -> tuple[float, float]:
    """Where the next round goes: the most probable hypothesis not yet flown over (no earlier round
    centre within ``visit_m``), else the estimate.  Why: a square around a wrong estimate teaches
    little; flying over each competing peak in turn either finds the transmitter's near field or
    removes that peak."""
    for x, y, _ in candidates or []:
        if all(np.hypot(x - vx, y - vy) > visit_m for vx, vy in visited):
            return float(x), float(y)
    return float(est_xy[0]), float(est_xy[1])


# A hypothesis holding this share of the peaks' mass has won: the round refines around the estimate
REFINE_MASS = 0.8


def disagreement(model, hyps_xy, mass, pts, tx_height_m: float) -> float:
    """How well RSS sampled at ``pts`` (Q, 3) tells the hypotheses ``hyps_xy`` (H, 2) apart: the
    sum over pairs of mass_i mass_j var_q(P_i(q) - P_j(q)), each P_i the RSS ``model`` predicts with
    the transmitter at hypothesis i.  The variance profiles out the per-flight offset: two
    hypotheses that differ by a constant along the pattern cannot be told apart there."""
    h = np.asarray(hyps_xy, dtype=float)
    m = np.asarray(mass, dtype=float)
    tx = np.column_stack([h, np.full(len(h), tx_height_m)])[:, None, :]
    p = np.asarray(model.rss_dbm(tx, np.asarray(pts, dtype=float)), dtype=float)  # (H, Q)
    var = (p[:, None, :] - p[None, :, :]).var(axis=-1)  # (H, H)
    return float(np.triu(m[:, None] * m[None, :] * var, 1).sum())


def separating_target(spec, a, est_xy, candidates, visited, start) -> tuple[float, float]:
    """Where the next round tells the live hypotheses (``candidates`` [x, y, mass], most probable
    first) apart best (``disagreement`` along the round's square flown there), among the
    hypotheses, the estimate and the midpoints of the top three; the estimate once one hypothesis
    holds ``REFINE_MASS`` of their mass (refine around the winner) or when no option is left.
    An option whose square, moved inside the fence, repeats a flown round's (``visited``) or fits
    nowhere is skipped."""
    est = (float(est_xy[0]), float(est_xy[1]))
    cands = np.asarray(candidates or [], dtype=float).reshape(-1, 3)
    if len(cands) < 2 or cands[0, 2] >= REFINE_MASS * cands[:, 2].sum():
        return est
    hyps, mass = cands[:, :2], cands[:, 2] / max(cands[:, 2].sum(), 1e-12)
    top = hyps[:3]
    mids = [(top[i] + top[j]) / 2 for i in range(len(top)) for j in range(i + 1, len(top))]
    options = [*hyps, np.array(est), *mids]
    model, kin, alt = spec.propagation_model(), spec.kinematics(), a.altitude(spec)
    best, best_score = est, -1.0
    for o in options:
        c = fit_centre(spec, o, a.radius_m)
        if c is None or _flown(c, visited, a.radius_m):
            continue
        _, pts = plan_profile(box_pattern(c, a.radius_m, alt, start), kin).sample(1.0)
        score = disagreement(model, hyps, mass, pts, spec.source.tx_height_m)
        if score > best_score:
            best, best_score = (float(o[0]), float(o[1])), score
    return best


def _flown(centre, visited, r: float) -> bool:
    """Whether a square centred at ``centre`` repeats a flown round's (a centre within ``r``)."""
    return any(np.hypot(centre[0] - vx, centre[1] - vy) <= r for vx, vy in visited)


def flyable(spec, a, candidates, visited) -> list:
    """The candidates [x, y, mass] worth a round: their square (half side ``a.radius_m``), moved
    inside the fence (``fit_centre``), fits and does not repeat a flown round's square.  Why: a peak
    outside the flight area moved inside the fence can land on a square already flown."""
    out = []
    for x, y, m in candidates or []:
        c = fit_centre(spec, (x, y), a.radius_m)
        if c is not None and not _flown(c, visited, a.radius_m):
            out.append([x, y, m])
    return out


def round_target(spec, a, d: dict, visited, start) -> tuple[float, float]:
    """The next round's target from the live entry ``d``: the judge's pick (``JUDGED_PICK``,
    the candidate the networks' physics explains best) while its square is unflown
    (``a.answer_first``); else the separating choice (``a.separate``), the peak order over the
    ``flyable`` peaks (``a.explore``: ``choose_target``), or the estimate.  Why the pick first:
    on 146 stored SITL surveys it lay within 15 m of the transmitter on 132, round 1's target by
    the peak order on 19 (docs/adaptive.md)."""
    est, cands = (d["x_m"], d["y_m"]), d.get("candidates")
    pick = d.get(JUDGED_PICK)
    if a.answer_first and pick is not None and flyable(spec, a, [[*pick, 1.0]], visited):
        return float(pick[0]), float(pick[1])
    if a.separate:
        return separating_target(spec, a, est, cands, visited, start)
    flyable_cands = flyable(spec, a, cands, visited) if a.explore else None
    return choose_target(est, flyable_cands, visited, a.radius_m)


def rival_of(target, est_xy, candidates, visit_m: float) -> list[float] | None:
    """The hypothesis a round flown over ``target`` is meant to tell it apart from: the most
    probable candidate farther than ``visit_m`` from the target, else the estimate when it is that
    far, as [x, y, the candidates' mass within ``visit_m`` of it]; None when nothing competes."""
    tx, ty = target
    far = [(x, y) for x, y, _ in candidates or [] if np.hypot(x - tx, y - ty) > visit_m]
    if not far and np.hypot(est_xy[0] - tx, est_xy[1] - ty) > visit_m:
        far = [tuple(est_xy)]
    if not far:
        return None
    x, y = far[0]
    return [float(x), float(y), mass_near((x, y), candidates, visit_m)]


def mass_near(xy, candidates, visit_m: float) -> float:
    """The posterior mass the candidates [x, y, mass] hold within ``visit_m`` of ``xy``."""
    return float(
        sum(m for x, y, m in candidates or [] if np.hypot(x - xy[0], y - xy[1]) <= visit_m)
    )


def verdict(hypotheses: dict, candidates_after, visit_m: float, drop: float = RULED_OUT_DROP):
    """Which of a round's two hypotheses (``{"target": [x, y, mass], "rival": [x, y, mass]}``, each
    mass the posterior's within ``visit_m`` when the round was planned) the estimate after it ruled
    out: the one whose mass there fell below ``drop`` of what it held while the other's did not
    ("target", "rival"), else None (both stand, or both fell)."""
    fell = [
        k
        for k, h in hypotheses.items()
        if h is not None and mass_near(h[:2], candidates_after, visit_m) < drop * max(h[2], 1e-9)
    ]
    return fell[0] if len(fell) == 1 and len(hypotheses) == 2 else None


def leg_violations(spec, start, wps) -> list:
    """Fence and altitude violations of flying ``start`` -> ``wps`` (``check_mission``'s rules; its
    time check, which assumes a flight from home, is replaced by the caller's budget check)."""
    path = np.vstack([np.asarray(start, dtype=float)[None, :], wps])
    rep = check_mission(dataclasses.replace(spec, trajectory=TrajectorySpec("waypoints", {}, path)))
    return [v for v in rep.violations if v.key not in ("time_budget_s", "source.tx")]


@dataclass
class RoundPlan:
    """A planned round (``waypoints`` None: refused, ``reason`` says why) with its timing and what
    was changed."""

    waypoints: np.ndarray | None
    centre: tuple[float, float] | None = None
    radius_m: float = 0.0
    fly_s: float = 0.0  # from the start point through the round
    return_s: float = 0.0  # from its last waypoint home, down and disarmed
    notes: list[str] = field(default_factory=list)
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.waypoints is not None


def round_fly_s(spec, wps: np.ndarray, start, pace=None) -> float:
    """Seconds to fly a round's waypoints ``wps`` from ``start``: the mission's kinematics, at the
    measured ``pace`` when given."""
    path = np.vstack([np.asarray(start, dtype=float)[None, :], wps])
    fly = plan_profile(path, spec.kinematics()).duration_s
    return fly if pace is None else pace.flown(fly, len(wps))


def smallest_round_s(spec, a, start, pace=None) -> float:
    """Seconds the smallest round (``a.min_radius_m``) over ``start`` takes from there: the least
    any next round needs."""
    xy = np.asarray(start, dtype=float)[:2]
    return round_fly_s(spec, box_pattern(xy, a.min_radius_m, a.altitude(spec), start), start, pace)


def plan_round(
    spec, a, est_xy, start, t_start_s: float, pace=None, returns: ReturnModel | None = None
) -> RoundPlan:
    """The next round around ``est_xy`` flown from ``start`` (3,), which the vehicle reaches
    ``t_start_s`` after take-off; it must end with the return and ``a.reserve_s`` inside the time
    budget.  ``pace`` (``trajectory.autopilot.Pace``: the pace measured in flight) turns the
    kinematic time of the round's legs into the time the autopilot will take (PX4 SITL flew its
    rounds in 84 and 66 s against 53 and 50 s planned); ``returns`` is the autopilot's return
    from the round's end (default: the mission's kinematics, no climb), flown at that pace."""
    alt = a.altitude(spec)
    returns = returns or ReturnModel.of(spec)
    notes: list[str] = []
    left = spec.time_budget_s - t_start_s - a.reserve_s
    r = float(a.radius_m)
    while r >= a.min_radius_m - 1e-9:
        c = fit_centre(spec, est_xy, r)
        if c is None:
            notes.append(f"a {2 * r:.0f} m square fits nowhere inside the fence")
        else:
            wps = box_pattern(c, r, alt, start)
            fly = round_fly_s(spec, wps, start, pace)
            back = returns.seconds(wps[-1], pace)
            bad = leg_violations(spec, start, wps)
            if bad:
                notes.append(f"refused a {2 * r:.0f} m square: {bad[0].message}")
            elif fly + back <= left:
                moved = float(np.hypot(*(c - np.asarray(est_xy, dtype=float)[:2])))
                if moved > 0.5:
                    notes.append(f"centre moved {moved:.0f} m to keep the fence margin")
                if r < a.radius_m:
                    notes.append(f"square shrunk to {2 * r:.0f} m to fit")
                return RoundPlan(wps, (float(c[0]), float(c[1])), r, fly, back, notes)
            else:
                notes.append(
                    f"a {2 * r:.0f} m square needs {fly + back:.0f} s with the return, "
                    f"{max(left, 0):.0f} s "
                    "left"
                )
        r = r * 0.7 if r * 0.7 >= a.min_radius_m or r <= a.min_radius_m else a.min_radius_m
    return RoundPlan(None, notes=notes, reason=notes[-1] if notes else "no round fits")
