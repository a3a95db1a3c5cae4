"""RSS sources behind one interface: ``sim`` (the propagation model), ``aerpaw-fifo`` and ``udp``
receivers.

Why one interface: the runner logs whatever produces RSS the same way, so a flight with a real
receiver and a simulated one give identical logs.  A source is drained by the log task with the
telemetry's coverage time; it returns the sample times (vehicle clock) it has up to then and, for
receivers, their values.  The ``sim`` source instead *evaluates* the model at the logged (already
rounded) position and attitude of each row, with one noise draw per row in row order, so a log's RSS
is exactly reproducible offline from its positions, attitudes and seed (see ``SimSource.evaluate``
and ``recompute_sim_rss``).

Receivers (``aerpaw-fifo``, ``udp``) time-stamp a value when it arrives with the vehicle clock
estimate (``telemetry.VehicleClock``); ``stalled_for`` lets the runner warn when a source stops
delivering.
"""

from __future__ import annotations

import asyncio
import os
import socket
import stat
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.flightlog.schema import QUALITY_COLUMN


class RssSource:
    """Base class: ``start``/``stop`` around a flight, ``drain(t_until)`` -> (times, values or
    None)."""

    kind = "base"
    needs_model = False
    extra_columns: tuple[str, ...] = ()

    def __init__(self) -> None:
        self.last_sample_wall = time.monotonic()
        self.count = 0

    async def start(self, clock: Callable[[], float]) -> None:
        """Begin receiving; ``clock()`` gives the vehicle time now."""
        self.clock = clock
        self.last_sample_wall = time.monotonic()

    async def stop(self) -> None:
        """Stop receiving (idempotent)."""

    def drain(self, t_until: float) -> tuple[np.ndarray, np.ndarray | None, dict[str, np.ndarray]]:
        """Samples with time <= ``t_until``: times, values (None: evaluate the model), extra
        columns."""
        raise NotImplementedError

    def stalled_for(self) -> float:
        """Wall-clock seconds since the source last delivered a sample."""
        return time.monotonic() - self.last_sample_wall

    def meta(self) -> dict:
        """What the sidecar records about the source."""
        return {"kind": self.kind, "calibrated": False}


class SimSource(RssSource):
    """The propagation model evaluated at each logged row; noise from a seeded Generator, one draw
    per row."""

    kind = "sim"
    needs_model = True

    def __init__(
        self,
        model,
        tx_enu: np.ndarray,
        rng: np.random.Generator,
        noise_db: float,
        period_s: float,
        origin,
        info: dict | None = None,
    ) -> None:
        super().__init__()
        self.model, self.tx, self.rng = model, np.asarray(tx_enu, dtype=float), rng
        self.noise_db, self.period, self.origin = float(noise_db), float(period_s), origin
        self.info = info or {}
        self.t0: float | None = None
        self.k = 0

    def drain(self, t_until: float):
        if not np.isfinite(t_until):
            return np.empty(0), None, {}
        if self.t0 is None:
            self.t0 = t_until
        k_end = int(np.floor((t_until - self.t0) / self.period + 1e-9))
        if k_end < self.k:
            return np.empty(0), None, {}
        t = self.t0 + self.period * np.arange(self.k, k_end + 1)
        self.k = k_end + 1
        if len(t):
            self.last_sample_wall = time.monotonic()
            self.count += len(t)
        return t, None, {}

    def evaluate(
        self, lat: np.ndarray, lon: np.ndarray, alt: np.ndarray, att_deg: np.ndarray
    ) -> np.ndarray:
        """RSS (dBm) at the logged positions/attitudes (the logged decimals) plus the next noise
        draws."""
        enu = self.origin.to_enu(lat, lon, alt)
        rss = np.asarray(
            self.model.rss_dbm(self.tx, enu, np.deg2rad(att_deg)), dtype=float
        ).reshape(-1)
        return rss + self.rng.normal(0.0, self.noise_db, size=rss.shape)

    def meta(self) -> dict:
        return {
            "kind": "sim",
            "calibrated": True,
            "noise_db": self.noise_db,
            "sample_period_s": self.period,
            "noise_order": "one normal(0, noise_db) draw per logged row, in row order, after "
            "tx resolution",
            **self.info,
        }


class _QueueSource(RssSource):
    """A receiver: values arrive on another thread or callback and are stamped with the vehicle
    clock."""

    def __init__(self) -> None:
        super().__init__()
        self._q: deque[tuple[float, float, float]] = deque()
        self._lock = threading.Lock()
        self.clock: Callable[[], float] = lambda: float("nan")

    def push(self, value: float, extra: float = float("nan")) -> None:
        """A value arriving now, stamped with the vehicle clock; ``extra``: its extra column's
        value (``extra_columns``, at most one)."""
        self._enqueue(self.clock(), value, extra)

    def _enqueue(self, t: float, value: float, extra: float = float("nan")) -> None:
        """Queue a value stamped ``t`` (kept increasing: a repeat moves 0.1 ms on)."""
        if not np.isfinite(t) or not np.isfinite(value):
            return
        with self._lock:
            if self._q and t <= self._q[-1][0]:
                t = self._q[-1][0] + 1e-4
            self._q.append((t, value, extra))
        self.last_sample_wall = time.monotonic()
        self.count += 1

    def drain(self, t_until: float):
        out = []
        with self._lock:
            while self._q and self._q[0][0] <= t_until:
                out.append(self._q.popleft())
        if not out:
            return np.empty(0), np.empty(0), {c: np.empty(0) for c in self.extra_columns}
        a = np.asarray(out)
        extra = {c: a[:, 2] for c in self.extra_columns}
        return a[:, 0], a[:, 1], extra


def parse_float32_le(buf: bytes) -> np.ndarray:
    """Little-endian float32 values of a byte buffer (its length a multiple of 4)."""
    return np.frombuffer(buf, dtype="<f4").astype(float)


PAIR_WAIT_S = 1.0  # a power value whose quality has not come within this is logged without it


class FifoSource(_QueueSource):
    """AERPAW's channel sounder output: little-endian float32 dB values in a named pipe (or a
    growing file).

    A named pipe is read from its start (the writer may open it later; a closed writer is waited for
    again); a regular file is followed from its current end, like ``tail -f``.

    ``quality_path``: the sounder's quality pipe (correlation peak over noise, dB; one value per
    correlation window, as the power), logged as ``QUALITY_COLUMN`` so that a diagnosis can tell the
    samples read out of lock (``rfsl gap --lock``).  The n-th quality value goes with the n-th power
    value; a power value whose quality has not come within ``PAIR_WAIT_S`` is logged without it
    (NaN, counted in ``quality_missing``) and that quality value is dropped when it comes, so the
    pairs after it keep their order and no power value waits on a silent quality pipe.
    """

    kind = "aerpaw-fifo"

    def __init__(self, path: str | Path, quality_path: str | Path | None = None) -> None:
        super().__init__()
        self.path = Path(path)
        self.quality_path = None if quality_path is None else Path(quality_path)
        for p in (self.path, self.quality_path):
            if p is not None and not p.exists():
                raise InputError("no such file or named pipe", source=str(p), field="--rss-source")
        self.extra_columns = () if self.quality_path is None else (QUALITY_COLUMN,)
        self._stop = threading.Event()
        self._pair_lock = threading.Lock()
        self._power: deque[tuple[int, float, float, float]] = deque()  # index, t, dB, wall
        self._quality: deque[tuple[int, float]] = deque()  # index, dB
        self._n_power = self._n_quality = 0
        self.quality_missing = 0

    async def start(self, clock):
        await super().start(clock)
        self.clock = clock
        readers = [(self.path, self.push if self.quality_path is None else self._on_power)]
        if self.quality_path is not None:
            readers.append((self.quality_path, self._on_quality))
        for k, (path, on_value) in enumerate(readers):
            threading.Thread(
                target=self._reader, args=(path, on_value), name=f"rss-fifo-{k}", daemon=True
            ).start()

    def _on_power(self, value: float) -> None:
        with self._pair_lock:
            self._power.append((self._n_power, self.clock(), value, time.monotonic()))
            self._n_power += 1
        self._pair()

    def _on_quality(self, value: float) -> None:
        with self._pair_lock:
            self._quality.append((self._n_quality, value))
            self._n_quality += 1
        self._pair()

    def _pair(self, flush_before_wall: float = -np.inf) -> None:
        """Queue every power value whose quality has come (dropping the quality values of powers
        already logged without one), then, without their quality, the powers that arrived before
        ``flush_before_wall``."""
        with self._pair_lock:
            while self._power:
                i, t, v, wall = self._power[0]
                while self._quality and self._quality[0][0] < i:
                    self._quality.popleft()
                if self._quality and self._quality[0][0] == i:
                    self._enqueue(t, v, self._quality.popleft()[1])
                elif wall < flush_before_wall:
                    self._enqueue(t, v)
                    self.quality_missing += 1
                else:
                    break
                self._power.popleft()

    def drain(self, t_until: float):
        """As ``_QueueSource.drain``, after pairing; the last drain (``t_until`` infinite: the
        log's end) logs every power value still waiting for its quality."""
        if self.quality_path is not None:
            wait = np.inf if not np.isfinite(t_until) else time.monotonic() - PAIR_WAIT_S
            self._pair(flush_before_wall=wait)
        return super().drain(t_until)

    def _reader(self, path: Path, on_value: Callable[[float], None]) -> None:
        is_fifo = stat.S_ISFIFO(os.stat(path).st_mode)
        rest = b""
        while not self._stop.is_set():
            try:
                fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
            except OSError:
                time.sleep(0.2)
                continue
            try:
                if not is_fifo:
                    os.lseek(fd, 0, os.SEEK_END)
                had_writer = False
                while not self._stop.is_set():
                    try:
                        chunk = os.read(fd, 4096)
                    except BlockingIOError:
                        chunk = None
                    if chunk:
                        had_writer = True
                        buf = rest + chunk
                        n = len(buf) // 4 * 4
                        rest = buf[n:]
                        for v in parse_float32_le(buf[:n]):
                            on_value(float(v))
                        continue
                    if chunk == b"" and is_fifo and had_writer:
                        break  # writer closed: reopen and wait for the next one
                    time.sleep(0.005)
            finally:
                os.close(fd)

    async def stop(self):
        self._stop.set()

    def meta(self) -> dict:
        out = {
            "kind": self.kind,
            "path": str(self.path),
            "calibrated": False,
            "note": "uncalibrated dB from the channel sounder (float32 little-endian)",
        }
        if self.quality_path is not None:
            out["quality_path"] = str(self.quality_path)
        return out


class UdpSource(_QueueSource):
    """Datagrams from another receiver: 4 bytes = one float32 little-endian, or text ``t,rss`` /
    ``rss``.

    The value is time-stamped on arrival with the vehicle clock; a sender's own ``t`` is kept in the
    extra column ``src_t_s`` (its clock is not the vehicle's, so it is not used for alignment).
    """

    kind = "udp"
    extra_columns = ("src_t_s",)

    def __init__(self, host: str, port: int) -> None:
        super().__init__()
        self.host, self.port = host, int(port)
        self._transport = None

    async def start(self, clock):
        await super().start(clock)
        self.clock = clock
        loop = asyncio.get_running_loop()
        src = self

        class _Proto(asyncio.DatagramProtocol):
            def datagram_received(self, data: bytes, addr) -> None:
                src.on_datagram(data)

        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((self.host, self.port))
        self.port = sock.getsockname()[1]
        self._transport, _ = await loop.create_datagram_endpoint(_Proto, sock=sock)

    def on_datagram(self, data: bytes) -> None:
        if len(data) == 4:
            self.push(struct.unpack("<f", data)[0])
            return
        try:
            parts = data.decode("ascii").strip().split(",")
            if len(parts) == 2:
                self.push(float(parts[1]), float(parts[0]))
            elif len(parts) == 1:
                self.push(float(parts[0]))
        except (UnicodeDecodeError, ValueError):
            pass  # not a sample: ignored (counted as nothing)

    async def stop(self):
        if self._transport is not None:
            self._transport.close()

    def meta(self) -> dict:
        return {"kind": self.kind, "bind": f"{self.host}:{self.port}", "calibrated": False}


def parse_source(text: str) -> tuple[str, str | None]:
    """``sim`` | ``aerpaw-fifo:PATH[,QUALITY_PATH]`` | ``udp:[HOST:]PORT`` -> (kind, argument)."""
    kind, _, arg = text.partition(":")
    if kind not in ("sim", "aerpaw-fifo", "udp"):
        raise InputError(
            f"unknown RSS source {text!r}; use sim, aerpaw-fifo:PATH[,QUALITY_PATH] or "
            "udp:[HOST:]PORT",
            field="--rss-source",
        )
    if kind != "sim" and not arg:
        raise InputError(f"RSS source {kind} needs an argument ({kind}:...)", field="--rss-source")
    return kind, arg or None


def fifo_paths(arg: str) -> tuple[str, str | None]:
    """``PATH[,QUALITY_PATH]`` -> (power pipe, quality pipe or None)."""
    power, _, quality = arg.partition(",")
    if not power or (_ and not quality):
        raise InputError(
            f"aerpaw-fifo:{arg}: expected PATH or PATH,QUALITY_PATH", field="--rss-source"
        )
    return power, quality or None


def make_receiver(kind: str, arg: str) -> RssSource:
    """Build a receiver source (``aerpaw-fifo`` or ``udp``) from its argument."""
    if kind == "aerpaw-fifo":
        return FifoSource(*fifo_paths(arg))
    host, _, port = arg.rpartition(":")
    try:
        return UdpSource(host or "0.0.0.0", int(port))
    except ValueError:
        raise InputError(f"bad UDP port in {arg!r}", field="--rss-source") from None


def recompute_sim_rss(
    log, model, seed_rng: np.random.Generator, tx_enu: np.ndarray, noise_db: float
) -> np.ndarray:
    """Offline: the sim source's RSS for a log's rows (same model, tx and generator state) ->
    (N,)."""
    enu = log.enu()
    att = np.stack([log["roll_deg"], log["pitch_deg"], log["yaw_deg"]], axis=-1)
    rss = np.asarray(
        model.rss_dbm(np.asarray(tx_enu, float), enu, np.deg2rad(att)), dtype=float
    ).reshape(-1)
    return rss + seed_rng.normal(0.0, noise_db, size=rss.shape)
