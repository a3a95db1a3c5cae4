"""The workshop: simulated datasets, the unseen-flight benchmark suites, training and evaluation.

It builds and scores what the runtime (``mission.localize``) runs on a log; it imports the runtime,
and the runtime never imports it (``tests/test_import_cycles.py`` checks this).
"""
