"""The live-estimate worker stops cleanly: after ``stop_worker`` nothing is left for Python's exit
hook to write to.

Why: a CI run of "connecting to nothing" printed "Exception ignored ... OSError: [Errno 9] Bad file
descriptor" after its one-line error.  Python 3.11's ``concurrent.futures`` exit hook wakes each
executor's manager thread through a pipe without the lock that its close takes; an exit while the
manager was closing it (the worker just killed) raced.  Without the join in ``stop_worker`` the
pipe was still open right after the stop on 10 of 10 tries."""

from __future__ import annotations

import time

import pytest

from mission.flight.estimates import LiveEstimates


@pytest.mark.parametrize("after_s", [0.0, 0.05, 0.3])
def test_stop_worker_leaves_the_executors_wakeup_closed(after_s):
    lv = LiveEstimates()
    lv.start_worker()
    time.sleep(after_s)  # still importing, or warmed up
    wake = lv.pool._executor_manager_thread_wakeup  # the pipe the exit hook writes to (private)
    t0 = time.monotonic()
    lv.stop_worker()
    assert wake._closed
    assert time.monotonic() - t0 < 5.0  # an estimate in the worker does not hold up the exit
