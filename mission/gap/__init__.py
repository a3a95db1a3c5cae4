"""Sim-to-real gap diagnosis (issue 6): where a propagation model departs from measured RSS, which
unmodelled effect explains it, and how much adding it helps (``rfsl gap``).

Modules: ``align`` (per-sample geometry), ``stats`` (block bootstrap), ``pipeline`` (physics model + time
offset, receiver, spatial shadowing), ``candidates`` (the effect library), ``fit`` (free constants,
candidate fits, ranking, greedy ladder), ``diagnose`` (the whole analysis), ``report`` (tables, PNGs, JSON),
``selftest`` (withheld-effect checks).
"""
