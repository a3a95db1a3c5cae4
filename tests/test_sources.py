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

from mission.flight.sources import FifoSource, SimSource, UdpSource, parse_float32_le, parse_source
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


def test_fifo_named_pipe_from_another_process(tmp_path):
    fifo = tmp_path / "Power"
    os.mkfifo(fifo)

    async def main():
        src = FifoSource(fifo)
        await src.start(_Clock())
        w = subprocess.Popen([sys.executable, "-c", WRITER, str(fifo)])
        for _ in range(100):
            await asyncio.sleep(0.05)
            if src.count >= 6:
                break
        w.wait(10)
        t, v, _ = src.drain(np.inf)
        await src.stop()
        return t, v

    t, v = asyncio.run(main())
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
