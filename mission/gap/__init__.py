"""Sim-to-real gap diagnosis (issues 6, 11): where a propagation model departs from measured RSS,
which unmodelled effect explains it, how large it is and where it acts, and how much adding it helps
(``rfsl gap``).

Modules: ``align`` (per-sample geometry), ``stats`` (block bootstrap), ``pipeline`` (physics model +
time offset, receiver, spatial shadowing), ``candidate`` (the candidate interface and ranking
tiers), ``candidates`` (the named effect library), ``freeform`` (smooth maps the data draws),
``spatial`` (kriging, a smoother), ``temporal`` (a gain drifting or stepping over a flight's time,
and what the flights can show along time), ``frame`` (ground-fixed or body-fixed: which map holds
out across headings and on unseen ground), ``fit`` (free constants, candidate fits, ranking rule,
greedy ladder), ``structure`` (residual variograms, effect footprints, what is named), ``diagnose``
(the whole analysis), ``report`` (tables, PNGs, ``gap.json``), ``selftest`` (withheld-effect checks
with the library's own physics).  Docs: ``README.md``.
"""
