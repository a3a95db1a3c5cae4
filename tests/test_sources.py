"""RSS sources: the AERPAW named pipe (written by another process), UDP datagrams, the sim source
order."""

from __future__ import annotations

import asyncio
import os
import socket
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

from mission.errors import InputError
from mission.flight import sources
from mission.flight.preflight import check_rss_source
from mission.flight.sources import (
    FifoSource,
    SimSource,
    UdpSource,
    fifo_paths,
    make_receiver,
    parse_float32_le,
    parse_source,
)
from mission.flightlog.schema import QUALITY_COLUMN
from mission.geo import Origin


class _Clock:
    def __init__(self) -> None:
        self.t0 = time.monotonic()

    def __call__(self) -> float:
        # a vehicle 10x faster than the wall clock
        return 100.0 + (time.monotonic() - self.t0) * 10.0


WRITER = """
import struct, sys, time
vals = [-61.25, -60.5, -59.75, -58.0, -57.125, -56.5]
with open(sys.argv[1], "wb", buffering=0) as f:
    for v in vals:
        f.write(struct.pack("<f", v))
        time.sleep(0.05)
"""


def _read_from_writer(src: FifoSource, writer: str, paths: list, n: int):
    """(times, values, extra columns) that ``src`` read while another process ran ``writer`` on
    ``paths``, once it had ``n`` values (or 5 s passed)."""

    async def main():
        await src.start(_Clock())
        w = subprocess.Popen([sys.executable, "-c", writer, *map(str, paths)])
        for _ in range(100):
            await asyncio.sleep(0.05)
            if src.count >= n:
                break
        w.wait(10)
        out = src.drain(np.inf)
        await src.stop()
        return out

    return asyncio.run(main())


def test_fifo_named_pipe_from_another_process(tmp_path):
    fifo = tmp_path / "Power"
    os.mkfifo(fifo)
    t, v, _ = _read_from_writer(FifoSource(fifo), WRITER, [fifo], 6)
    assert list(v) == [-61.25, -60.5, -59.75, -58.0, -57.125, -56.5]
    assert np.all(np.diff(t) > 0) and t[0] >= 100.0


def test_float32_matches_aerpaw_values():
    # values like those of afar2023/aerpaw_logs/*_power_log.txt (od -f output of the sounder's
    # float32)
    vals = np.array([-38.7461, -41.2059, -52.8867], dtype="<f4")
    assert np.allclose(parse_float32_le(vals.tobytes()), vals.astype(float))


def test_udp_text_and_float32():
    async def main():
        src = UdpSource("127.0.0.1", 0)
        await src.start(_Clock())
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.sendto(b"12.5,-47.25", ("127.0.0.1", src.port))
        s.sendto(struct.pack("<f", -48.5), ("127.0.0.1", src.port))
        s.sendto(b"garbage,,", ("127.0.0.1", src.port))
        for _ in range(50):
            await asyncio.sleep(0.02)
            if src.count >= 2:
                break
        t, v, extra = src.drain(np.inf)
        await src.stop()
        s.close()
        return v, extra

    v, extra = asyncio.run(main())
    assert list(v) == [-47.25, -48.5]
    assert extra["src_t_s"][0] == 12.5 and np.isnan(extra["src_t_s"][1])


def test_sim_source_grid_and_noise_order():
    class Flat:
        def rss_dbm(self, tx, rx, att):
            return np.full(len(rx), -50.0)

    o = Origin(35.0, -78.0, 0.0)
    src = SimSource(Flat(), np.zeros(3), np.random.default_rng(3), 1.0, 0.03, o)
    t1, v1, _ = src.drain(10.0)
    t2, _, _ = src.drain(10.1)
    assert v1 is None and len(t1) == 1 and np.allclose(np.diff(np.r_[t1, t2]), 0.03)
    a = src.evaluate(np.full(2, 35.0), np.full(2, -78.0), np.zeros(2), np.zeros((2, 3)))
    b = src.evaluate(np.full(3, 35.0), np.full(3, -78.0), np.zeros(3), np.zeros((3, 3)))
    ref = -50.0 + np.random.default_rng(3).normal(0.0, 1.0, 5)  # batches draw as one stream
    assert np.allclose(np.r_[a, b], ref)


def test_parse_source():
    assert parse_source("sim") == ("sim", None)
    assert parse_source("aerpaw-fifo:/root/Power") == ("aerpaw-fifo", "/root/Power")
    assert parse_source("udp:0.0.0.0:5005") == ("udp", "0.0.0.0:5005")


PAIRED_WRITER = """
import struct, sys, time
power = [-61.25, -60.5, -59.75, -58.0]
quality = [71.5, 70.25, 44.0, 72.0]
with open(sys.argv[1], "wb", buffering=0) as p, open(sys.argv[2], "wb", buffering=0) as q:
    for i, (a, b) in enumerate(zip(power, quality)):
        p.write(struct.pack("<f", a))
        if i == 2:  # the second quality value comes late, after the third power value
            q.write(struct.pack("<f", quality[1]))
        if i != 1:
            q.write(struct.pack("<f", b))
        time.sleep(0.05)
"""


def test_fifo_pairs_each_power_with_its_quality_from_two_pipes(tmp_path):
    """``aerpaw-fifo:POWER,QUALITY``: the n-th quality value is logged beside the n-th power value
    as ``rss_quality_db``, whichever pipe delivers first."""
    power, quality = tmp_path / "Power", tmp_path / "Quality"
    os.mkfifo(power)
    os.mkfifo(quality)

    src = make_receiver(*parse_source(f"aerpaw-fifo:{power},{quality}"))
    t, v, extra = _read_from_writer(src, PAIRED_WRITER, [power, quality], 4)
    assert list(v) == [-61.25, -60.5, -59.75, -58.0]
    assert list(extra[QUALITY_COLUMN]) == [71.5, 70.25, 44.0, 72.0]
    assert np.all(np.diff(t) > 0) and src.quality_missing == 0
    assert src.meta()["quality_path"] == str(quality)


def test_fifo_power_never_waits_on_a_silent_quality_pipe(tmp_path, monkeypatch):
    """A power value whose quality has not come within ``PAIR_WAIT_S`` is logged without it (NaN,
    counted), its quality is dropped when it comes, and the next pair keeps its index; the log's
    last drain keeps every power value still waiting."""
    (tmp_path / "P").write_bytes(b"")
    (tmp_path / "Q").write_bytes(b"")
    src = FifoSource(tmp_path / "P", tmp_path / "Q")
    src.clock = lambda: 10.0
    wall = [0.0]
    monkeypatch.setattr(sources.time, "monotonic", lambda: wall[0])
    src._on_power(-50.0)
    src._on_power(-51.0)
    src._on_quality(70.0)
    wall[0] = 0.5  # the second power waited half a second: kept waiting
    t, v, extra = src.drain(20.0)
    assert list(v) == [-50.0] and list(extra[QUALITY_COLUMN]) == [70.0]
    wall[0] = 0.5 + sources.PAIR_WAIT_S + 0.1
    t, v, extra = src.drain(20.0)
    assert list(v) == [-51.0] and np.isnan(extra[QUALITY_COLUMN]).all()
    assert src.quality_missing == 1
    src._on_quality(69.0)  # the late quality of -51: dropped
    src._on_power(-52.0)
    src._on_quality(68.0)
    src._on_power(-53.0)  # no quality yet: the last drain logs it anyway
    t, v, extra = src.drain(np.inf)
    assert list(v) == [-52.0, -53.0]
    assert extra[QUALITY_COLUMN][0] == 68.0 and np.isnan(extra[QUALITY_COLUMN][1])


def test_fifo_paths_and_preflight(tmp_path):
    """``PATH[,QUALITY_PATH]``: both pipes checked before the flight, a half-given pair refused."""
    assert fifo_paths("/root/Power") == ("/root/Power", None)
    assert fifo_paths("/root/Power,/root/Quality") == ("/root/Power", "/root/Quality")
    for bad in ("/root/Power,", ",/root/Quality"):
        with pytest.raises(InputError, match="PATH,QUALITY_PATH"):
            fifo_paths(bad)
    (tmp_path / "Power").write_bytes(b"")
    with pytest.raises(InputError, match="Quality"):
        check_rss_source(f"aerpaw-fifo:{tmp_path / 'Power'},{tmp_path / 'Quality'}")
    check_rss_source(f"aerpaw-fifo:{tmp_path / 'Power'}")
