"""``sitl.shared``: starting, watching and stopping a SITL from its start script, on stand-in
scripts that behave like ../shared's (print the PID, write the log in $RUN)."""

from __future__ import annotations

import socket
import stat
from pathlib import Path

import pytest

from sitl.shared import SharedSitl, SitlStartError, free_instance


def _script(tmp_path: Path, body: str) -> Path:
    """A start.sh whose SITL is ``body`` run in the background with its output in $RUN/sitl.log."""
    p = tmp_path / "start.sh"
    p.write_text(f'#!/bin/sh\n( {body} ) > "$RUN/sitl.log" 2>&1 &\necho $!\n')
    p.chmod(p.stat().st_mode | stat.S_IEXEC)
    return p


def test_launch_waits_for_ready_and_stop_ends_it(tmp_path):
    sitl = SharedSitl(tmp_path / "run")
    script = _script(tmp_path, "sleep 0.5; echo Waiting for connection; exec sleep 60")
    pid = sitl.launch(script, [], "Waiting for connection", "stand-in SITL")
    assert pid == sitl.pid and sitl.alive() and "Waiting for connection" in sitl.log()
    sitl.stop()
    assert not sitl.alive()
    sitl.stop()  # a second stop of a stopped SITL is harmless


def test_a_sitl_that_dies_before_ready_is_an_error_with_its_log(tmp_path):
    sitl = SharedSitl(tmp_path / "run")
    script = _script(tmp_path, "echo 'bad parameter file'; exit 1")
    with pytest.raises(SitlStartError, match="stand-in SITL did not start: bad parameter file"):
        sitl.launch(script, [], "Ready for takeoff!", "stand-in SITL")
    assert not sitl.alive()


def test_free_instance_skips_taken_ports():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        taken = s.getsockname()[1]
        assert free_instance(1, 1, lambda i: (taken,), udp=False) is None
        i = free_instance(1, 5, lambda i: (taken if i < 5 else 0,), udp=False)
        assert i == 5
